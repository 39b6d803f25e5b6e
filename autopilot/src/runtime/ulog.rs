//! ULog encoder: PX4's self-describing binary log format (little endian), as pure functions from values
//! to bytes, with no file, clock or channel. The writer task (`runtime::flight_log`) puts the bytes on
//! disk; Flight Review, PlotJuggler, `pyulog` and QGroundControl read them.
//!
//! A file is: the 16-byte header (magic `ULog` 0x01 0x12 0x35, version 1, start timestamp in µs), then
//! the flag bits ('B', right after the header, with the compat flag that says default parameters are
//! present, as PX4 writes it), the definitions (formats 'F', information 'I', parameters 'P' and their
//! defaults 'Q'), then the data section: subscriptions 'A', data 'D', logged strings 'L' and sync markers
//! 'S'. Each message is a 3-byte header (u16 size of what follows, u8 type) and its body, so a message
//! body is at most 65 535 bytes; longer ones are refused ([`UlogError::TooLong`]) rather than cut.
//!
//! [`Topic`] is a format with its field list; [`Record`] builds one data payload field by field and
//! [`Topic::data`] checks it against the format before it becomes a message, so a record that does not
//! match its format never reaches a file. [`read_messages`] splits a file back into messages (tests and
//! tools).

/// The file magic, then the version byte.
pub const MAGIC: [u8; 7] = [b'U', b'L', b'o', b'g', 0x01, 0x12, 0x35];
/// The file format version PX4 writes.
pub const FILE_VERSION: u8 = 1;
/// Length of the file header (magic, version, timestamp), in bytes.
pub const HEADER_BYTES: usize = 16;
/// Length of a message's header (u16 size, u8 type), in bytes.
pub const MESSAGE_HEADER_BYTES: usize = 3;
/// The body of a sync message.
pub const SYNC_MAGIC: [u8; 8] = [0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12];
/// Compat flag 0, bit 0: the file carries default parameters ('Q' messages); what PX4 sets.
pub const COMPAT_FLAG0_DEFAULT_PARAMETERS: u8 = 1;
/// `default_types` bit of a 'Q' message: the system-wide default.
pub const DEFAULT_TYPE_SYSTEM: u8 = 1;
/// `default_types` bit of a 'Q' message: the default for the current configuration (airframe).
pub const DEFAULT_TYPE_CONFIGURATION: u8 = 2;

/// Why bytes could not be made or read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum UlogError {
    #[error("ULog message body of {bytes} bytes is over the format's 65535")]
    TooLong { bytes: usize },
    #[error("key or name `{0}` is longer than 255 bytes or empty")]
    BadKey(String),
    #[error("data for `{topic}` is {got} bytes; its format says {want}")]
    SizeMismatch { topic: String, got: usize, want: usize },
    #[error("not a ULog file (magic or version)")]
    BadHeader,
    #[error("message at byte {offset_bytes} is cut short")]
    Truncated { offset_bytes: usize },
}

/// A field's base type, with the name the format string gives it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldType {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F32,
    F64,
    Bool,
    Char,
}

impl FieldType {
    /// The C type name of the format string.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Self::U8 => "uint8_t",
            Self::I8 => "int8_t",
            Self::U16 => "uint16_t",
            Self::I16 => "int16_t",
            Self::U32 => "uint32_t",
            Self::I32 => "int32_t",
            Self::U64 => "uint64_t",
            Self::I64 => "int64_t",
            Self::F32 => "float",
            Self::F64 => "double",
            Self::Bool => "bool",
            Self::Char => "char",
        }
    }

    /// Size of one element, in bytes.
    #[must_use]
    pub const fn size_bytes(self) -> usize {
        match self {
            Self::U8 | Self::I8 | Self::Bool | Self::Char => 1,
            Self::U16 | Self::I16 => 2,
            Self::U32 | Self::I32 | Self::F32 => 4,
            Self::U64 | Self::I64 | Self::F64 => 8,
        }
    }
}

/// One field of a format: a type, an array length (1: a scalar) and a name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub ty: FieldType,
    pub len: usize,
    pub name: String,
}

impl Field {
    #[must_use]
    pub fn scalar(ty: FieldType, name: &str) -> Self {
        Self { ty, len: 1, name: name.to_owned() }
    }

    #[must_use]
    pub fn array(ty: FieldType, len: usize, name: &str) -> Self {
        Self { ty, len, name: name.to_owned() }
    }

    /// `type name` or `type[len] name`.
    #[must_use]
    pub fn declaration(&self) -> String {
        if self.len == 1 {
            format!("{} {}", self.ty.name(), self.name)
        } else {
            format!("{}[{}] {}", self.ty.name(), self.len, self.name)
        }
    }

    #[must_use]
    pub fn size_bytes(&self) -> usize {
        self.ty.size_bytes() * self.len
    }
}

/// A logged topic: its name, its fields (the first is `uint64_t timestamp` in µs, as every PX4 topic),
/// and the message id its data go under once subscribed.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Topic {
    pub name: String,
    pub fields: Vec<Field>,
    pub msg_id: u16,
}

impl Topic {
    /// A topic whose fields follow a leading `uint64_t timestamp`.
    #[must_use]
    pub fn new(name: &str, msg_id: u16, fields: Vec<Field>) -> Self {
        let mut all = vec![Field::scalar(FieldType::U64, "timestamp")];
        all.extend(fields);
        Self { name: name.to_owned(), fields: all, msg_id }
    }

    /// `name:type field;type field;...` as the 'F' message carries it.
    #[must_use]
    pub fn format_string(&self) -> String {
        let mut s = format!("{}:", self.name);
        for f in &self.fields {
            s.push_str(&f.declaration());
            s.push(';');
        }
        s
    }

    /// Size of one data payload (no padding: fields are written back to back).
    #[must_use]
    pub fn size_bytes(&self) -> usize {
        self.fields.iter().map(Field::size_bytes).sum()
    }

    /// The 'F' message defining this topic's format.
    ///
    /// # Errors
    /// [`UlogError::TooLong`] for a format string over 65 535 bytes.
    pub fn format_message(&self) -> Result<Vec<u8>, UlogError> {
        message(b'F', self.format_string().as_bytes())
    }

    /// The 'A' message subscribing this topic (instance `multi_id`) under its message id.
    ///
    /// # Errors
    /// [`UlogError::TooLong`] for an absurdly long name.
    pub fn subscription(&self, multi_id: u8) -> Result<Vec<u8>, UlogError> {
        let mut body = vec![multi_id];
        body.extend_from_slice(&self.msg_id.to_le_bytes());
        body.extend_from_slice(self.name.as_bytes());
        message(b'A', &body)
    }

    /// The 'D' message carrying `record` for this topic.
    ///
    /// # Errors
    /// [`UlogError::SizeMismatch`] when the record is not exactly one payload of this format.
    pub fn data(&self, record: &Record) -> Result<Vec<u8>, UlogError> {
        let want = self.size_bytes();
        if record.bytes.len() != want {
            return Err(UlogError::SizeMismatch { topic: self.name.clone(), got: record.bytes.len(), want });
        }
        let mut body = Vec::with_capacity(2 + want);
        body.extend_from_slice(&self.msg_id.to_le_bytes());
        body.extend_from_slice(&record.bytes);
        message(b'D', &body)
    }
}

/// One data payload, built field by field in the order of its topic's format.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Record {
    bytes: Vec<u8>,
}

impl Record {
    /// A payload starting with its timestamp (µs).
    #[must_use]
    pub fn new(timestamp_us: u64) -> Self {
        Self { bytes: timestamp_us.to_le_bytes().to_vec() }
    }

    #[must_use]
    pub fn u8(mut self, v: u8) -> Self {
        self.bytes.push(v);
        self
    }

    #[must_use]
    pub fn bool(self, v: bool) -> Self {
        self.u8(u8::from(v))
    }

    #[must_use]
    pub fn u16(mut self, v: u16) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    #[must_use]
    pub fn u32(mut self, v: u32) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    #[must_use]
    pub fn i32(mut self, v: i32) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    #[must_use]
    pub fn u64(mut self, v: u64) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    #[must_use]
    pub fn f64(mut self, v: f64) -> Self {
        self.bytes.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A float field from an f64 (narrowed, as the topics are float).
    #[must_use]
    pub fn f32(mut self, v: f64) -> Self {
        self.bytes.extend_from_slice(&(v as f32).to_le_bytes());
        self
    }

    /// A float array field.
    #[must_use]
    pub fn f32s(self, values: &[f64]) -> Self {
        values.iter().fold(self, |r, &v| r.f32(v))
    }

    /// Bytes so far.
    #[must_use]
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }
}

/// A message of type `kind` with `body`.
///
/// # Errors
/// [`UlogError::TooLong`] for a body over 65 535 bytes.
pub fn message(kind: u8, body: &[u8]) -> Result<Vec<u8>, UlogError> {
    let size = u16::try_from(body.len()).map_err(|_| UlogError::TooLong { bytes: body.len() })?;
    let mut out = Vec::with_capacity(MESSAGE_HEADER_BYTES + body.len());
    out.extend_from_slice(&size.to_le_bytes());
    out.push(kind);
    out.extend_from_slice(body);
    Ok(out)
}

/// The file header: magic, version, and the time logging started (µs of the vehicle clock).
#[must_use]
pub fn header(timestamp_us: u64) -> [u8; HEADER_BYTES] {
    let mut out = [0u8; HEADER_BYTES];
    out[..7].copy_from_slice(&MAGIC);
    out[7] = FILE_VERSION;
    out[8..].copy_from_slice(&timestamp_us.to_le_bytes());
    out
}

/// The flag bits ('B') PX4 writes right after the header: compat flag DEFAULT_PARAMETERS, no incompat
/// flags (no appended data), no appended offsets.
#[must_use]
pub fn flag_bits() -> Vec<u8> {
    let mut body = [0u8; 40];
    body[0] = COMPAT_FLAG0_DEFAULT_PARAMETERS;
    // A 40-byte body always fits.
    message(b'B', &body).unwrap_or_default()
}

/// A value of an information or parameter message.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    Str(String),
    I32(i32),
    U32(u32),
    F32(f32),
}

impl Value {
    /// The key's type (`char[len]`, `int32_t`, ...).
    fn type_name(&self) -> String {
        match self {
            Self::Str(s) => format!("char[{}]", s.len()),
            Self::I32(_) => "int32_t".to_owned(),
            Self::U32(_) => "uint32_t".to_owned(),
            Self::F32(_) => "float".to_owned(),
        }
    }

    fn bytes(&self) -> Vec<u8> {
        match self {
            Self::Str(s) => s.as_bytes().to_vec(),
            Self::I32(v) => v.to_le_bytes().to_vec(),
            Self::U32(v) => v.to_le_bytes().to_vec(),
            Self::F32(v) => v.to_le_bytes().to_vec(),
        }
    }
}

/// `key_len`, `type name` and the value's bytes: the body shared by 'I', 'P' and 'Q'.
fn key_value(name: &str, value: &Value) -> Result<Vec<u8>, UlogError> {
    let key = format!("{} {name}", value.type_name());
    let key_len = u8::try_from(key.len()).map_err(|_| UlogError::BadKey(name.to_owned()))?;
    if name.is_empty() {
        return Err(UlogError::BadKey(String::new()));
    }
    let mut body = vec![key_len];
    body.extend_from_slice(key.as_bytes());
    body.extend_from_slice(&value.bytes());
    Ok(body)
}

/// An information message ('I'): `sys_name`, `ver_sw`, `time_ref_utc`...
///
/// # Errors
/// [`UlogError::BadKey`] or [`UlogError::TooLong`].
pub fn info(name: &str, value: &Value) -> Result<Vec<u8>, UlogError> {
    message(b'I', &key_value(name, value)?)
}

/// A parameter message ('P'): PX4 types parameters as `int32_t` or `float`.
///
/// # Errors
/// [`UlogError::BadKey`] or [`UlogError::TooLong`].
pub fn parameter(name: &str, value: &Value) -> Result<Vec<u8>, UlogError> {
    message(b'P', &key_value(name, value)?)
}

/// A default-parameter message ('Q'): the default of `name` for the groups in `default_types`
/// ([`DEFAULT_TYPE_SYSTEM`], [`DEFAULT_TYPE_CONFIGURATION`]).
///
/// # Errors
/// [`UlogError::BadKey`] or [`UlogError::TooLong`].
pub fn default_parameter(default_types: u8, name: &str, value: &Value) -> Result<Vec<u8>, UlogError> {
    let mut body = vec![default_types];
    body.extend(key_value(name, value)?);
    message(b'Q', &body)
}

/// A logged string ('L'): a syslog level as an ASCII digit ('0' emergency .. '7' debug, as MAVLink's
/// severities), the vehicle time (µs) and the text. `level` above 7 is logged as 7.
///
/// # Errors
/// [`UlogError::TooLong`] for a text over 65 525 bytes.
pub fn logged_string(level: u8, timestamp_us: u64, text: &str) -> Result<Vec<u8>, UlogError> {
    let mut body = vec![b'0' + level.min(7)];
    body.extend_from_slice(&timestamp_us.to_le_bytes());
    body.extend_from_slice(text.as_bytes());
    message(b'L', &body)
}

/// A sync marker ('S'), which lets a reader find message boundaries again in a damaged file.
#[must_use]
pub fn sync() -> Vec<u8> {
    message(b'S', &SYNC_MAGIC).unwrap_or_default()
}

/// A dropout marker ('O'): `duration_ms` of data were lost (the writer fell behind).
#[must_use]
pub fn dropout(duration_ms: u16) -> Vec<u8> {
    message(b'O', &duration_ms.to_le_bytes()).unwrap_or_default()
}

/// One message read back: its type and body.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReadMessage {
    pub kind: u8,
    pub body: Vec<u8>,
}

/// Check the header and split the rest into messages; returns the header's timestamp too.
///
/// # Errors
/// [`UlogError::BadHeader`] for a file that is not ULog version 1, [`UlogError::Truncated`] at a
/// message cut short.
pub fn read_messages(bytes: &[u8]) -> Result<(u64, Vec<ReadMessage>), UlogError> {
    let head = bytes.get(..HEADER_BYTES).ok_or(UlogError::BadHeader)?;
    if head[..7] != MAGIC || head[7] != FILE_VERSION {
        return Err(UlogError::BadHeader);
    }
    let mut stamp = [0u8; 8];
    stamp.copy_from_slice(&head[8..]);
    let mut out = Vec::new();
    let mut at = HEADER_BYTES;
    while at < bytes.len() {
        let truncated = UlogError::Truncated { offset_bytes: at };
        let h = bytes.get(at..at + MESSAGE_HEADER_BYTES).ok_or(truncated.clone())?;
        let size = usize::from(u16::from_le_bytes([h[0], h[1]]));
        let start = at + MESSAGE_HEADER_BYTES;
        let body = bytes.get(start..start + size).ok_or(truncated)?;
        out.push(ReadMessage { kind: h[2], body: body.to_vec() });
        at = start + size;
    }
    Ok((u64::from_le_bytes(stamp), out))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn topic() -> Topic {
        Topic::new(
            "vehicle_attitude",
            3,
            vec![Field::scalar(FieldType::U64, "timestamp_sample"), Field::array(FieldType::F32, 4, "q")],
        )
    }

    #[test]
    fn the_header_is_the_magic_version_1_and_the_timestamp() {
        let h = header(0x0102_0304_0506_0708);
        assert_eq!(&h[..8], b"ULog\x01\x12\x35\x01");
        assert_eq!(&h[8..], &[8, 7, 6, 5, 4, 3, 2, 1]);
    }

    #[test]
    fn the_flag_bits_are_40_bytes_with_the_default_parameters_flag_only() {
        let b = flag_bits();
        assert_eq!(&b[..3], &[40, 0, b'B']);
        assert_eq!(b[3], COMPAT_FLAG0_DEFAULT_PARAMETERS);
        assert!(b[4..].iter().all(|&x| x == 0), "no other compat, no incompat flags, no appended offsets");
    }

    #[test]
    fn a_format_string_lists_the_timestamp_first_then_the_fields() {
        let t = topic();
        assert_eq!(t.format_string(), "vehicle_attitude:uint64_t timestamp;uint64_t timestamp_sample;float[4] q;");
        assert_eq!(t.size_bytes(), 8 + 8 + 16);
        let f = t.format_message().expect("fits");
        assert_eq!(usize::from(u16::from_le_bytes([f[0], f[1]])), t.format_string().len());
        assert_eq!(f[2], b'F');
    }

    #[test]
    fn data_of_the_right_size_becomes_a_message_and_of_the_wrong_size_is_refused() {
        let t = topic();
        let r = Record::new(5).u64(4).f32s(&[1.0, 0.0, 0.0, 0.0]);
        let d = t.data(&r).expect("matches");
        assert_eq!(d.len(), MESSAGE_HEADER_BYTES + 2 + 32);
        assert_eq!(&d[..5], &[34, 0, b'D', 3, 0]);
        assert_eq!(&d[5..13], &5u64.to_le_bytes());
        assert_eq!(&d[21..25], &1.0f32.to_le_bytes());
        let short = Record::new(5).u64(4).f32s(&[1.0, 0.0, 0.0]);
        assert_eq!(
            t.data(&short),
            Err(UlogError::SizeMismatch { topic: "vehicle_attitude".into(), got: 28, want: 32 })
        );
    }

    #[test]
    fn info_and_parameters_carry_their_c_type_in_the_key() {
        let i = info("sys_name", &Value::Str("ACO".into())).expect("ok");
        assert_eq!(i[2], b'I');
        assert_eq!(usize::from(i[3]), "char[3] sys_name".len());
        assert_eq!(&i[4..20], b"char[3] sys_name");
        assert_eq!(&i[20..], b"ACO");
        let p = parameter("SDLOG_MODE", &Value::I32(-1)).expect("ok");
        assert_eq!(&p[4..4 + usize::from(p[3])], b"int32_t SDLOG_MODE");
        assert_eq!(&p[p.len() - 4..], &(-1i32).to_le_bytes());
        let q = default_parameter(DEFAULT_TYPE_SYSTEM, "MPC_XY_CRUISE", &Value::F32(5.0)).expect("ok");
        assert_eq!((q[2], q[3]), (b'Q', DEFAULT_TYPE_SYSTEM));
        assert_eq!(&q[5..5 + usize::from(q[4])], b"float MPC_XY_CRUISE");
        assert!(matches!(info("", &Value::U32(1)), Err(UlogError::BadKey(_))));
        assert!(matches!(info(&"x".repeat(300), &Value::U32(1)), Err(UlogError::BadKey(_))));
    }

    #[test]
    fn a_logged_string_has_its_level_digit_and_timestamp() {
        let l = logged_string(6, 1_000_000, "Mode: Hold").expect("ok");
        assert_eq!((l[2], l[3]), (b'L', b'6'));
        assert_eq!(&l[4..12], &1_000_000u64.to_le_bytes());
        assert_eq!(&l[12..], b"Mode: Hold");
        assert_eq!(logged_string(42, 0, "x").expect("ok")[3], b'7');
        assert!(matches!(logged_string(0, 0, &"x".repeat(70_000)), Err(UlogError::TooLong { .. })));
    }

    #[test]
    fn a_file_made_of_every_message_reads_back_message_by_message() {
        let t = topic();
        let mut file = header(42).to_vec();
        let parts = [
            flag_bits(),
            t.format_message().expect("ok"),
            info("ver_sw", &Value::Str("abc".into())).expect("ok"),
            parameter("X", &Value::F32(1.5)).expect("ok"),
            t.subscription(0).expect("ok"),
            t.data(&Record::new(1).u64(1).f32s(&[1.0; 4])).expect("ok"),
            logged_string(4, 2, "hi").expect("ok"),
            sync(),
            dropout(7),
        ];
        for p in &parts {
            file.extend_from_slice(p);
        }
        let (stamp, read) = read_messages(&file).expect("parses");
        assert_eq!(stamp, 42);
        let kinds: Vec<u8> = read.iter().map(|m| m.kind).collect();
        assert_eq!(kinds, b"BFIPADLSO".to_vec());
        for (m, p) in read.iter().zip(&parts) {
            assert_eq!(m.body, p[MESSAGE_HEADER_BYTES..]);
        }
        assert_eq!(
            read[4].body,
            [0, 3, 0, b'v', b'e', b'h', b'i', b'c', b'l', b'e', b'_', b'a', b't', b't', b'i', b't', b'u', b'd', b'e']
        );
        assert_eq!(read[7].body, SYNC_MAGIC);
        // Cut short, or not a ULog file at all: an error, never a panic.
        assert!(matches!(read_messages(&file[..file.len() - 1]), Err(UlogError::Truncated { .. })));
        assert_eq!(read_messages(b"ULog"), Err(UlogError::BadHeader));
        assert_eq!(read_messages(&[0u8; 40]), Err(UlogError::BadHeader));
    }
}
