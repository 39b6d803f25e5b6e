use super::*;
use ::mavlink::dialects::common::{
    ATTITUDE_DATA, AUTOPILOT_VERSION_DATA, COMMAND_ACK_DATA, DEBUG_VECT_DATA, HEARTBEAT_DATA, MISSION_CURRENT_DATA,
    MISSION_ITEM_INT_DATA, PARAM_VALUE_DATA, STATUSTEXT_DATA,
};
use proptest::prelude::*;
use std::collections::VecDeque;

const ATTITUDE: StreamKey = StreamKey::of_id(30);

fn attitude() -> MavMessage {
    MavMessage::ATTITUDE(ATTITUDE_DATA::default())
}

#[test]
fn messages_are_classed_priority_transfer_or_stream() {
    let heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA::default());
    let text = MavMessage::STATUSTEXT(STATUSTEXT_DATA::default());
    for m in [&heartbeat, &ack, &text] {
        assert_eq!(classify(m, false), Class::Priority);
        assert_eq!(classify(m, true), Class::Priority, "a reply too");
    }
    let param = MavMessage::PARAM_VALUE(PARAM_VALUE_DATA::default());
    let item = MavMessage::MISSION_ITEM_INT(MISSION_ITEM_INT_DATA::default());
    let version = MavMessage::AUTOPILOT_VERSION(AUTOPILOT_VERSION_DATA::default());
    for m in [&param, &item, &version] {
        assert_eq!(classify(m, false), Class::Transfer);
    }
    assert_eq!(classify(&attitude(), false), Class::Stream(ATTITUDE));
    assert_eq!(classify(&attitude(), true), Class::Transfer, "a reply to one peer is never thinned");
    // MISSION_CURRENT is a telemetry stream, whatever its name.
    let current = MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA::default());
    assert_eq!(classify(&current, false), Class::Stream(StreamKey::of_id(42)));
    // Every stream of telemetry.rs is one.
    for s in Stream::ALL {
        assert!(!PRIORITY_IDS.contains(&s.message_id()), "{s:?}");
    }
    // The weight vectors are a stream each.
    let vect = |name: &str| MavMessage::DEBUG_VECT(DEBUG_VECT_DATA { name: name.into(), ..DEBUG_VECT_DATA::default() });
    assert_ne!(classify(&vect("aco.w_t"), false), classify(&vect("aco.b_t"), false));
    assert_eq!(classify(&vect("aco.w_t"), false), classify(&vect("aco.w_t"), false));
}

#[test]
fn the_radio_halves_below_25_reduces_below_35_holds_to_50_raises_above_and_times_out() {
    let mut g = LinkGovernor::<()>::new(0);
    assert_eq!(g.mult(), 1.0);
    g.on_radio_status(0, 20);
    assert_eq!((g.radio_mult(), g.mult()), (0.5, 0.5));
    g.on_radio_status(1_000_000, 30);
    assert!((g.mult() - 0.4).abs() < 1e-12, "{}", g.mult());
    g.on_radio_status(2_000_000, 35);
    g.on_radio_status(3_000_000, 50);
    assert!((g.mult() - 0.4).abs() < 1e-12, "held: {}", g.mult());
    g.on_radio_status(4_000_000, 51);
    assert!((g.mult() - 0.5).abs() < 1e-12, "{}", g.mult());
    for k in 0..3 {
        g.on_radio_status(5_000_000 + k * 1_000_000, 100);
    }
    assert!((g.mult() - 0.5 * 1.25_f64.powi(3)).abs() < 1e-12, "{}", g.mult());
    g.on_radio_status(8_000_000, 100);
    assert_eq!(g.mult(), 1.0, "up to 1, not beyond");
    for k in 0..10 {
        g.on_radio_status(8_000_000 + k * 1_000_000, 0);
    }
    assert_eq!(g.mult(), MULT_MIN, "never below 5 %");
    g.update(17_000_000 + RADIO_TIMEOUT_US);
    assert_eq!(g.mult(), MULT_MIN, "5 s is not yet a timeout");
    g.update(17_000_001 + RADIO_TIMEOUT_US);
    assert_eq!(g.mult(), 1.0, "a silent radio resets its multiplier");
    assert_eq!(g.counters().radio_status, 19);
}

#[test]
fn a_20_hz_stream_at_half_goes_at_10_hz_exactly_and_evenly() {
    let mut g = LinkGovernor::<u64>::new(0);
    g.on_radio_status(0, 20);
    let mut kept = Vec::new();
    for k in 0..200_u64 {
        let t = k * 50_000;
        if k % 20 == 0 {
            g.on_radio_status(t, 40); // hold it at 0.5
        }
        if g.offer_message(t, &attitude(), false, 40, k) == Offered::Queued {
            kept.extend(g.pop(t));
        }
    }
    assert_eq!(kept.len(), 100);
    assert!(kept.windows(2).all(|w| w[1] - w[0] == 2), "every other one: {kept:?}");
    let c = g.counters().stream;
    assert_eq!((c.offered, c.sent, c.thinned), (200, 100, 100));
    // At 0.05, one in twenty.
    let mut g = LinkGovernor::<u64>::new(0);
    for k in 0..10 {
        g.on_radio_status(0, k);
    }
    assert_eq!(g.mult(), MULT_MIN);
    let kept = (0..400_u64).filter(|&k| g.offer_message(0, &attitude(), false, 40, k) == Offered::Queued).count();
    assert_eq!(kept, 20);
}

#[test]
fn the_bandwidth_thins_the_streams_to_what_the_link_carries_after_the_rest() {
    // 5760 B/s; streams offered at 11 520 B/s (288 frames of 40 bytes a second): about half.
    let mut g = LinkGovernor::<()>::new(5760);
    let mut t = 0;
    for _ in 0..10_000 {
        t += 3_472;
        g.offer(t, Class::Stream(ATTITUDE), 40, ());
        while g.pop(t).is_some() {}
    }
    assert!((g.mult() - 0.5).abs() < 0.02, "{}", g.mult());
    // Streams at 2900 B/s fit: full rate.
    let mut g = LinkGovernor::<()>::new(5760);
    let mut t = 0;
    for _ in 0..2000 {
        t += 13_793;
        g.offer(t, Class::Stream(ATTITUDE), 40, ());
        while g.pop(t).is_some() {}
    }
    assert_eq!(g.mult(), 1.0);
    // A parameter download on top (8 kB in 60 ms) takes the room: the streams give way for a while.
    for k in 0..228 {
        g.offer(t + k * 250, Class::Transfer, 37, ());
    }
    assert!(g.mult() < 0.1, "{}", g.mult());
    g.update(t + 4_000_000);
    assert_eq!(g.mult(), 1.0, "and come back");
}

#[test]
fn priority_goes_first_then_transfers_in_order_then_the_newest_of_each_stream() {
    let mut g = LinkGovernor::<&str>::new(0);
    g.offer(0, Class::Stream(ATTITUDE), 40, "attitude 1");
    g.offer(0, Class::Stream(StreamKey::of_id(1)), 40, "sys_status");
    g.offer(0, Class::Transfer, 37, "param 0");
    g.offer(0, Class::Stream(ATTITUDE), 40, "attitude 2");
    g.offer(0, Class::Transfer, 37, "param 1");
    g.offer(0, Class::Priority, 21, "heartbeat");
    let order: Vec<_> = std::iter::from_fn(|| g.pop(0)).collect();
    assert_eq!(order, ["heartbeat", "param 0", "param 1", "attitude 2", "sys_status"]);
    assert_eq!(g.counters().stream.superseded, 1);
    assert!(g.is_idle());
}

#[test]
fn the_pacer_writes_at_the_data_rate_and_says_when_the_next_frame_may_go() {
    let mut g = LinkGovernor::<u32>::new(1000);
    for k in 0..100 {
        g.offer(0, Class::Transfer, 50, k);
    }
    // The bucket holds one frame's worth (280 bytes): five at once.
    let first: Vec<_> = std::iter::from_fn(|| g.pop(0)).collect();
    assert_eq!(first.len(), 5);
    // 30 bytes in the bucket: 20 more needed, 20 ms at 1000 B/s.
    assert_eq!(g.next_ready_in_us(0), Some(20_000));
    assert_eq!(g.pop(19_999), None);
    assert_eq!(g.pop(20_000), Some(5));
    // Over 4.75 s more, 95 frames of 50 bytes.
    let mut sent = 6;
    let mut t = 20_000;
    while t < 4_770_000 {
        t += 10_000;
        sent += std::iter::from_fn(|| g.pop(t)).count();
    }
    assert_eq!(sent, 100);
    assert_eq!(g.next_ready_in_us(t), None, "nothing waits");
    assert_eq!(g.counters().transfer.sent_bytes, 5000);
}

#[test]
fn an_item_larger_than_a_frame_goes_when_the_bucket_is_full() {
    let mut g = LinkGovernor::<()>::new(1000);
    g.offer(0, Class::Transfer, 840, ());
    g.offer(0, Class::Transfer, 40, ());
    assert!(g.pop(0).is_some(), "a datagram for three peers");
    assert!(g.pop(0).is_none());
    // It overdrew by 560 bytes: 600 bytes, 600 ms, before the next 40.
    assert_eq!(g.next_ready_in_us(0), Some(600_000));
}

#[test]
fn the_unlimited_link_passes_everything_and_the_queues_are_capped() {
    let mut g = LinkGovernor::<usize>::new(0);
    for k in 0..TRANSFER_QUEUE_CAP + 3 {
        g.offer(0, Class::Transfer, 37, k);
    }
    assert_eq!(g.counters().transfer.dropped, 3);
    assert_eq!(std::iter::from_fn(|| g.pop(0)).count(), TRANSFER_QUEUE_CAP);
    for k in 0..PRIORITY_QUEUE_CAP + 1 {
        g.offer(0, Class::Priority, 21, k);
    }
    assert_eq!(g.pop(0), Some(1), "the oldest went");
    assert_eq!(g.counters().priority.dropped, 1);
}

#[test]
fn the_multiplier_is_reported_when_it_moves_and_loudly_past_a_factor_2() {
    let mut g = LinkGovernor::<()>::new(0);
    assert_eq!(g.take_mult_report(), None);
    g.on_radio_status(0, 30); // 0.8
    let r = g.take_mult_report().expect("moved 20 %");
    assert!(!r.loud && r.previous == 1.0);
    g.on_radio_status(0, 30); // 0.64
    assert!(!g.take_mult_report().expect("moved").loud, "0.64 is within 2x of 1");
    g.on_radio_status(0, 20); // 0.32
    assert!(g.take_mult_report().expect("moved").loud, "0.32 is past half of 1");
    assert_eq!(g.take_mult_report(), None, "told once");
    g.update(RADIO_TIMEOUT_US + 1);
    let r = g.take_mult_report().expect("back to 1");
    assert!(r.loud && r.mult == 1.0);
}

#[derive(Debug, Clone)]
enum Op {
    Priority(usize),
    Transfer(usize),
    Stream(u32, usize),
    Radio(u8),
    Pop,
}

fn op() -> impl Strategy<Value = (u64, Op)> {
    let bytes = 12..=MAX_FRAME_BYTES;
    (
        0..30_000_u64,
        prop_oneof![
            bytes.clone().prop_map(Op::Priority),
            bytes.clone().prop_map(Op::Transfer),
            (0..5_u32, bytes).prop_map(|(k, b)| Op::Stream(k, b)),
            (0..=100_u8).prop_map(Op::Radio),
            Just(Op::Pop),
            Just(Op::Pop),
        ],
    )
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Priority,
    Transfer,
    Stream,
}

/// What the property test expects of the governor.
#[derive(Debug, Default)]
struct Model {
    waiting_priority: VecDeque<usize>,
    waiting_transfer: VecDeque<usize>,
    /// (time, bytes) of every item handed out.
    written: Vec<(u64, usize)>,
    sizes: std::collections::HashMap<usize, usize>,
    /// When the last priority item and the last transfer were handed out (µs).
    last_priority_us: u64,
    last_transfer_us: u64,
}

impl Model {
    /// Takes what the governor hands out at `t`, checking the order.
    fn pop_all(&mut self, g: &mut LinkGovernor<(Kind, usize)>, t: u64) -> Result<(), TestCaseError> {
        while let Some((kind, id)) = g.pop(t) {
            match kind {
                Kind::Priority => {
                    prop_assert_eq!(self.waiting_priority.pop_front(), Some(id), "priority in order");
                    self.last_priority_us = t;
                }
                Kind::Transfer => {
                    prop_assert!(self.waiting_priority.is_empty(), "a transfer went before a waiting priority message");
                    prop_assert_eq!(self.waiting_transfer.pop_front(), Some(id), "transfers in order");
                    self.last_transfer_us = t;
                }
                Kind::Stream => {
                    prop_assert!(self.waiting_priority.is_empty(), "a stream went before a waiting priority message");
                    prop_assert!(self.waiting_transfer.is_empty(), "a stream went before a waiting transfer");
                }
            }
            self.written.push((t, self.sizes[&id]));
        }
        Ok(())
    }
}

proptest! {
    #[test]
    fn priority_is_never_dropped_nor_behind_a_stream_and_the_bytes_fit_the_rate(
        rate in prop_oneof![Just(0_u64), 500..100_000_u64],
        ops in proptest::collection::vec(op(), 1..400),
    ) {
        let mut g = LinkGovernor::<(Kind, usize)>::new(rate);
        let mut model = Model::default();
        let mut t = 0_u64;
        for (id, (dt, op)) in ops.into_iter().enumerate() {
            t += dt;
            match op {
                Op::Priority(b) => {
                    model.sizes.insert(id, b);
                    prop_assert_eq!(g.offer(t, Class::Priority, b, (Kind::Priority, id)), Offered::Queued);
                    model.waiting_priority.push_back(id);
                }
                Op::Transfer(b) => {
                    model.sizes.insert(id, b);
                    prop_assert_eq!(g.offer(t, Class::Transfer, b, (Kind::Transfer, id)), Offered::Queued);
                    model.waiting_transfer.push_back(id);
                }
                Op::Stream(k, b) => {
                    model.sizes.insert(id, b);
                    g.offer(t, Class::Stream(StreamKey::of_id(k)), b, (Kind::Stream, id));
                }
                Op::Radio(txbuf) => g.on_radio_status(t, txbuf),
                Op::Pop => model.pop_all(&mut g, t)?,
            }
            prop_assert!((MULT_MIN..=1.0).contains(&g.mult()), "mult {}", g.mult());
        }
        // The contract: what waits goes at the line's pace, polled when the governor says the next item
        // is ready (as the runtime's links sleep): every priority item by the priority bytes waiting over
        // the rate, every transfer by all the priority and transfer bytes waiting over the rate (each
        // item's readiness rounds up by at most 1 µs). Nothing waits longer than its bytes need.
        let waiting_bytes = |ids: &VecDeque<usize>| ids.iter().map(|id| model.sizes[id] as u64).sum::<u64>();
        let priority_bytes = waiting_bytes(&model.waiting_priority);
        let all_bytes = priority_bytes + waiting_bytes(&model.waiting_transfer);
        let items = (model.waiting_priority.len() + model.waiting_transfer.len()) as u64;
        let deadline_us = |bytes: u64| if rate == 0 { t } else { t + (bytes * 1_000_000).div_ceil(rate) + items };
        let (priority_deadline_us, transfer_deadline_us) = (deadline_us(priority_bytes), deadline_us(all_bytes));
        let (priority_waited, transfer_waited) = (!model.waiting_priority.is_empty(), !model.waiting_transfer.is_empty());
        while let Some(wait_us) = g.next_ready_in_us(t) {
            t += wait_us;
            model.pop_all(&mut g, t)?;
        }
        if priority_waited {
            prop_assert!(model.last_priority_us <= priority_deadline_us,
                "the last priority item went at {} µs, after {} µs", model.last_priority_us, priority_deadline_us);
        }
        if transfer_waited {
            prop_assert!(model.last_transfer_us <= transfer_deadline_us,
                "the last transfer went at {} µs, after {} µs", model.last_transfer_us, transfer_deadline_us);
        }
        prop_assert!(model.waiting_priority.is_empty() && model.waiting_transfer.is_empty());
        prop_assert_eq!(g.counters().priority.dropped + g.counters().transfer.dropped, 0);
        if rate > 0 {
            // Over any window [t_i, t_j]: bytes <= rate × window + one frame.
            let written = &model.written;
            for i in 0..written.len() {
                let mut sum = 0_u128;
                for &(tj, bytes) in &written[i..] {
                    sum += bytes as u128;
                    let window = u128::from(tj - written[i].0);
                    let allowed = u128::from(rate) * window + MAX_FRAME_BYTES as u128 * 1_000_000;
                    prop_assert!(sum * 1_000_000 <= allowed, "{} bytes in {} µs at {} B/s", sum, window, rate);
                }
            }
        }
    }
}
