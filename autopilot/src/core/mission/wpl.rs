//! The mission as persistence text: the QGC WPL 110 format that QGroundControl and MAVProxy read and write.
//! In: a [`Mission`] ([`Mission::to_wpl`]) or a text ([`Mission::from_wpl`]). Out: the text, or a
//! validated mission, or a [`WplError`] with the 1-based line number.
//!
//! The header line `QGC WPL 110`, then one line per item with 12 tab-separated fields: seq, current (1 on
//! item 0), frame, command, param1..param4, x (latitude deg), y (longitude deg), z (m), autocontinue.
//! Item 0 is the first mission item, as PX4 numbers them (Mission Planner files put home there instead).
//!
//! Exact round trip for what the wire carries: x and y are written from their integer form with exactly
//! as many decimals as the form has (7 for degE7, 4 for m * 1e4, none for MISSION-frame parameters), so
//! reading them back rounds to the same integer; f32 fields are written in the shortest form that reads
//! back to the same value (`NaN` and `inf` spelled out); unset x/y are `NaN`.
//!
//! Reading is as lenient as pymavlink's reader: fields may be separated by any whitespace, blank lines and
//! `#` comment lines are skipped, CRLF line ends are accepted.

use thiserror::Error;

use super::{
    Mission, MissionError, MissionItem, XY_UNSET, command_id, frame_id, supported_command, supported_frame,
    validate_item, xy_decimals, xy_from_float,
};

/// The first line of the text.
pub const WPL_HEADER: &str = "QGC WPL 110";

const FIELDS: [&str; 12] =
    ["seq", "current", "frame", "command", "param1", "param2", "param3", "param4", "x", "y", "z", "autocontinue"];

/// Why a WPL text is not a mission. `line` is 1-based.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum WplError {
    #[error("line 1: expected `{WPL_HEADER}`, found {found:?}")]
    Header { found: String },
    #[error("line {line}: {found} fields, expected 12")]
    FieldCount { line: usize, found: usize },
    #[error("line {line}: {field} {text:?} is not a valid number")]
    Number { line: usize, field: &'static str, text: String },
    #[error("line {line}: frame {frame} unsupported")]
    Frame { line: usize, frame: u32 },
    #[error("line {line}: command {command} unsupported")]
    Command { line: usize, command: u32 },
    #[error("line {line}: {source}")]
    Invalid { line: usize, source: MissionError },
}

/// An integer x/y as a decimal with `decimals` places, written exactly; [`XY_UNSET`] as `NaN`.
fn fixed_decimals(value: i32, decimals: u32) -> String {
    if value == XY_UNSET {
        return "NaN".into();
    }
    if decimals == 0 {
        return value.to_string();
    }
    let unit = 10_u32.pow(decimals);
    let abs = value.unsigned_abs();
    let sign = if value < 0 { "-" } else { "" };
    format!("{sign}{}.{:0width$}", abs / unit, abs % unit, width = decimals as usize)
}

impl Mission {
    /// The mission as QGC WPL 110 text (LF line ends, one line per item).
    #[must_use]
    pub fn to_wpl(&self) -> String {
        items_to_wpl(&self.items)
    }
}

/// Any plan's items (mission, fence or rally) as QGC WPL 110 text (LF line ends, one line per item).
#[must_use]
pub fn items_to_wpl(items: &[MissionItem]) -> String {
    {
        let mut text = format!("{WPL_HEADER}\n");
        for (i, item) in items.iter().enumerate() {
            let decimals = xy_decimals(item.frame);
            text.push_str(&format!(
                "{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\t{}\n",
                item.seq,
                u8::from(i == 0),
                frame_id(item.frame),
                command_id(item.command),
                item.param1,
                item.param2,
                item.param3,
                item.param4,
                fixed_decimals(item.x, decimals),
                fixed_decimals(item.y, decimals),
                item.z,
                u8::from(item.autocontinue),
            ));
        }
        text
    }
}

impl Mission {
    /// A mission from QGC WPL 110 text, validated as an upload is.
    ///
    /// # Errors
    /// [`WplError`] at the first bad line: header, field count, a number that does not parse, a frame or
    /// command this vehicle does not fly, a seq out of order or an item [`validate_item`] refuses.
    pub fn from_wpl(text: &str) -> Result<Self, WplError> {
        let (items, item_lines) = parse_items(text, supported_command)?;
        if items.len() > Self::MAX_ITEMS {
            let line = item_lines.get(Self::MAX_ITEMS).copied().unwrap_or_default();
            return Err(WplError::Invalid {
                line,
                source: MissionError::TooManyItems { count: items.len(), max: Self::MAX_ITEMS },
            });
        }
        for (item, &line) in items.iter().zip(&item_lines) {
            validate_item(item, items.len()).map_err(|source| WplError::Invalid { line, source })?;
        }
        Ok(Self { items })
    }
}

/// Any plan's items from QGC WPL 110 text, each command looked up by `command_of` (the plan's own
/// commands), in order, with their 1-based line numbers; not validated beyond frame, command and seq.
///
/// # Errors
/// [`WplError`] at the first bad line.
pub fn items_from_wpl(
    text: &str,
    command_of: impl Fn(u32) -> Option<::mavlink::dialects::common::MavCmd>,
) -> Result<Vec<MissionItem>, WplError> {
    parse_items(text, command_of).map(|(items, _)| items)
}

type CommandOf<'a> = &'a dyn Fn(u32) -> Option<::mavlink::dialects::common::MavCmd>;

fn parse_items(
    text: &str,
    command_of: impl Fn(u32) -> Option<::mavlink::dialects::common::MavCmd>,
) -> Result<(Vec<MissionItem>, Vec<usize>), WplError> {
    {
        let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l));
        let header = lines.next().map_or("", |(_, l)| l.trim_start_matches('\u{feff}').trim());
        if header != WPL_HEADER {
            return Err(WplError::Header { found: header.to_owned() });
        }
        let mut items = Vec::new();
        let mut item_lines = Vec::new();
        for (line, raw) in lines {
            let raw = raw.trim();
            if raw.is_empty() || raw.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = raw.split_whitespace().collect();
            if fields.len() != FIELDS.len() {
                return Err(WplError::FieldCount { line, found: fields.len() });
            }
            let item = parse_item(line, &fields, &command_of)?;
            if usize::from(item.seq) != items.len() {
                return Err(WplError::Invalid {
                    line,
                    source: MissionError::Sequence { index: items.len(), seq: item.seq },
                });
            }
            items.push(item);
            item_lines.push(line);
        }
        Ok((items, item_lines))
    }
}

fn parse_item(line: usize, fields: &[&str], command_of: CommandOf<'_>) -> Result<MissionItem, WplError> {
    let number_error = |i: usize| WplError::Number { line, field: FIELDS[i], text: fields[i].to_owned() };
    let int = |i: usize| fields[i].parse::<u32>().map_err(|_| number_error(i));
    let float = |i: usize| fields[i].parse::<f32>().map_err(|_| number_error(i));
    let seq = u16::try_from(int(0)?).map_err(|_| number_error(0))?;
    let _current = int(1)?;
    let frame_number = int(2)?;
    let frame = supported_frame(frame_number).ok_or(WplError::Frame { line, frame: frame_number })?;
    let command_number = int(3)?;
    let command = command_of(command_number).ok_or(WplError::Command { line, command: command_number })?;
    let xy =
        |i: usize| fields[i].parse::<f64>().ok().and_then(|v| xy_from_float(v, frame)).ok_or_else(|| number_error(i));
    Ok(MissionItem {
        seq,
        frame,
        command,
        param1: float(4)?,
        param2: float(5)?,
        param3: float(6)?,
        param4: float(7)?,
        x: xy(8)?,
        y: xy(9)?,
        z: float(10)?,
        autocontinue: int(11)? != 0,
    })
}

#[cfg(test)]
mod tests {
    use ::mavlink::dialects::common::{MavCmd, MavFrame};
    use proptest::prelude::*;

    use super::super::tests::{do_item, waypoint};
    use super::super::{LAT_LIMIT_DEGE7, LON_LIMIT_DEGE7};
    use super::*;

    /// Equal, with NaN equal to NaN (text carries NaN, not its payload bits).
    fn same_f32(a: f32, b: f32) -> bool {
        a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
    }

    fn same_item(a: &MissionItem, b: &MissionItem) -> bool {
        let fa = [a.param1, a.param2, a.param3, a.param4, a.z];
        let fb = [b.param1, b.param2, b.param3, b.param4, b.z];
        a.seq == b.seq
            && a.frame == b.frame
            && a.command == b.command
            && a.x == b.x
            && a.y == b.y
            && a.autocontinue == b.autocontinue
            && fa.iter().zip(fb).all(|(&x, y)| same_f32(x, y))
    }

    fn assert_round_trip(mission: &Mission) {
        let text = mission.to_wpl();
        let back = Mission::from_wpl(&text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back.items.len(), mission.items.len());
        for (a, b) in mission.items.iter().zip(&back.items) {
            assert!(same_item(a, b), "{a:?}\n{b:?}\n{text}");
        }
    }

    fn sample() -> Mission {
        Mission::new(vec![
            MissionItem { command: MavCmd::MAV_CMD_NAV_TAKEOFF, x: XY_UNSET, y: XY_UNSET, ..waypoint(0, 0, 0, 12.5) },
            waypoint(1, -353_632_621, 1_491_652_374, 20.1),
            MissionItem {
                frame: MavFrame::MAV_FRAME_GLOBAL_INT,
                ..waypoint(2, LAT_LIMIT_DEGE7, -LON_LIMIT_DEGE7, 0.1)
            },
            MissionItem { frame: MavFrame::MAV_FRAME_GLOBAL, ..waypoint(3, -1, 1, 488.25) },
            do_item(4, MavCmd::MAV_CMD_DO_CHANGE_SPEED, 1.0, 7.5),
            do_item(5, MavCmd::MAV_CMD_DO_JUMP, 1.0, 3.0),
            MissionItem { autocontinue: false, ..do_item(6, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, 0.0, 0.0) },
        ])
        .expect("valid")
    }

    #[test]
    fn given_a_mission_when_written_then_the_header_and_tab_separated_lines_as_qgc_writes_them() {
        let text = sample().to_wpl();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[0], "QGC WPL 110");
        assert_eq!(lines[2], "1\t0\t6\t16\t0\t0\t0\tNaN\t-35.3632621\t149.1652374\t20.1\t1");
        assert_eq!(lines[1].split('\t').nth(1), Some("1"), "item 0 is current");
        assert_eq!(lines[5], "4\t0\t2\t178\t1\t7.5\t0\t0\t0\t0\t0\t1");
        assert_eq!(lines.len(), 8);
    }

    #[test]
    fn given_a_mission_with_dege7_extremes_nan_and_unset_when_round_tripped_then_exactly_equal() {
        assert_round_trip(&sample());
        assert_round_trip(&Mission::default());
        assert_eq!(Mission::default().to_wpl(), "QGC WPL 110\n");
    }

    proptest! {
        #[test]
        fn given_any_waypoint_when_round_tripped_then_exact(
            x in -LAT_LIMIT_DEGE7..=LAT_LIMIT_DEGE7,
            y in -LON_LIMIT_DEGE7..=LON_LIMIT_DEGE7,
            z in proptest::num::f32::NORMAL | proptest::num::f32::ZERO | proptest::num::f32::SUBNORMAL,
            p in proptest::num::f32::ANY,
        ) {
            let item = MissionItem { param1: p, param2: p, param3: -p, param4: p, ..waypoint(0, x, y, z) };
            assert_round_trip(&Mission::new(vec![item]).expect("valid"));
        }
    }

    #[test]
    fn given_a_mavproxy_file_with_comments_spaces_and_crlf_when_read_then_items_at_their_precision() {
        let text = "QGC WPL 110\r\n# mission by MAVProxy\r\n0 0 3 22 0.000000 0.000000 0.000000 0.000000 \
                    -35.363262 149.165237 10.000000 1\r\n\r\n1\t0\t3\t16\t0.000000\t0.000000\t0.000000\t0.000000\t\
                    -35.361000\t149.163000\t20.000000\t1\r\n";
        let mission = Mission::from_wpl(text).expect("valid");
        assert_eq!(mission.len(), 2);
        assert_eq!((mission.items[0].x, mission.items[0].y), (-353_632_620, 1_491_652_370));
        assert_eq!(mission.items[1].command, MavCmd::MAV_CMD_NAV_WAYPOINT);
        assert_eq!(mission.items[1].z, 20.0);
    }

    #[test]
    fn given_bad_texts_when_read_then_the_error_names_the_line() {
        let wp = "0\t1\t3\t16\t0\t0\t0\t0\t47.1\t8.5\t10\t1";
        let cases: [(String, WplError); 7] = [
            (String::new(), WplError::Header { found: String::new() }),
            ("QGC WPL 100\n".into(), WplError::Header { found: "QGC WPL 100".into() }),
            (format!("QGC WPL 110\n{wp}\n1\t0\t3\t16\t0\n"), WplError::FieldCount { line: 3, found: 5 }),
            (
                format!("QGC WPL 110\n\n{}", wp.replace("47.1", "north")),
                WplError::Number { line: 3, field: "x", text: "north".into() },
            ),
            (format!("QGC WPL 110\n{}", wp.replace("\t3\t16", "\t1\t16")), WplError::Frame { line: 2, frame: 1 }),
            (format!("QGC WPL 110\n{}", wp.replace("\t16\t", "\t183\t")), WplError::Command { line: 2, command: 183 }),
            (
                format!("QGC WPL 110\n{wp}\n{}", wp.replacen('0', "2", 1)),
                WplError::Invalid { line: 3, source: MissionError::Sequence { index: 1, seq: 2 } },
            ),
        ];
        for (text, expected) in cases {
            assert_eq!(Mission::from_wpl(&text), Err(expected), "{text:?}");
        }
        let jump = format!("QGC WPL 110\n{wp}\n1\t0\t2\t177\t5\t1\t0\t0\t0\t0\t0\t1\n");
        let err = Mission::from_wpl(&jump).expect_err("jump out of range");
        assert!(matches!(err, WplError::Invalid { line: 3, source: MissionError::JumpTarget { .. } }), "{err}");
        assert!(err.to_string().starts_with("line 3: item 1: jump target 5"), "{err}");
    }
}
