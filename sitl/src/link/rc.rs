//! The plant's RC input port, as ArduPilot's SITL has one: the pilot's radio from a gamepad bridge or a
//! script, on UDP 127.0.0.1:[`RC_IN_PORT`] (`--rc-in-port`, 0 = off). Each datagram is 8 to 16
//! little-endian `u16` PWM values (µs), channels 1..N, each in [`RC_PWM_MIN_US`]..=[`RC_PWM_MAX_US`]; anything
//! else (an odd length, fewer than 8 or more than 16 values, a value out of range) is dropped whole and
//! counted, with one warning the first time. The last good datagram is held as the receiver's frame
//! ([`crate::plant::Radio::set_port_frame`]) until the next, as ArduPilot's SITL holds its RC input; the
//! plant link sends it as `RC_CHANNELS` at 50 Hz of plant time.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};

use autopilot::core::manual::RcFrame;

use crate::plant::radio::{RC_PWM_MAX_US, RC_PWM_MIN_US};

/// The default RC input port (ArduPilot SITL's, for instance 0).
pub const RC_IN_PORT: u16 = 5501;
/// Plant time between two `RC_CHANNELS` (µs): 50 Hz, a receiver's frame rate.
pub const RC_PERIOD_US: u64 = 20_000;

/// Whether the step at `time_us` (of length `dt_us`) is the first of an [`RC_PERIOD_US`] period.
#[must_use]
pub fn rc_due(time_us: u64, dt_us: u64) -> bool {
    time_us % RC_PERIOD_US < dt_us.max(1)
}

/// Fewest channels a datagram carries.
pub const RC_IN_MIN_CHANNELS: usize = 8;
/// Most channels a datagram carries.
pub const RC_IN_MAX_CHANNELS: usize = 16;

/// Why a datagram on the RC input port was dropped.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RcDatagramError {
    #[error("{0} bytes is not a whole number of u16 values")]
    OddLength(usize),
    #[error("{0} values: a datagram carries {RC_IN_MIN_CHANNELS} to {RC_IN_MAX_CHANNELS} little-endian u16 PWM values")]
    Count(usize),
    #[error("channel {channel} = {value_us} us is outside {RC_PWM_MIN_US}..={RC_PWM_MAX_US}")]
    Range { channel: usize, value_us: u16 },
}

/// One RC input datagram as a receiver frame (channels 1..N, signal strength unknown).
///
/// # Errors
/// [`RcDatagramError`] for anything but 8 to 16 little-endian `u16` values each in
/// [`RC_PWM_MIN_US`]..=[`RC_PWM_MAX_US`].
pub fn parse_rc_datagram(bytes: &[u8]) -> Result<RcFrame, RcDatagramError> {
    if !bytes.len().is_multiple_of(2) {
        return Err(RcDatagramError::OddLength(bytes.len()));
    }
    let n = bytes.len() / 2;
    if !(RC_IN_MIN_CHANNELS..=RC_IN_MAX_CHANNELS).contains(&n) {
        return Err(RcDatagramError::Count(n));
    }
    let mut values_us = [0_u16; RC_IN_MAX_CHANNELS];
    for (i, pair) in bytes.chunks_exact(2).enumerate() {
        let value_us = u16::from_le_bytes([pair[0], pair[1]]);
        if !(RC_PWM_MIN_US..=RC_PWM_MAX_US).contains(&value_us) {
            return Err(RcDatagramError::Range { channel: i + 1, value_us });
        }
        values_us[i] = value_us;
    }
    Ok(RcFrame::of(&values_us[..n]))
}

/// What the RC input port took and dropped; both only grow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RcInStats {
    pub accepted: u64,
    pub dropped: u64,
}

/// The RC input port's socket (non-blocking): each [`RcInPort::poll`] reads every datagram waiting and
/// returns the last good frame among them.
#[derive(Debug)]
pub struct RcInPort {
    socket: UdpSocket,
    stats: RcInStats,
    warned: bool,
    buf: Vec<u8>,
}

impl RcInPort {
    /// Bind `addr` (e.g. `127.0.0.1:5501`, or port 0 in tests).
    ///
    /// # Errors
    /// The bind or socket-option error.
    pub fn bind(addr: impl ToSocketAddrs) -> io::Result<Self> {
        let socket = UdpSocket::bind(addr)?;
        socket.set_nonblocking(true)?;
        // One byte more than the longest good datagram, so a longer one reads as too long, not cut.
        Ok(Self { socket, stats: RcInStats::default(), warned: false, buf: vec![0; 2 * RC_IN_MAX_CHANNELS + 1] })
    }

    /// The bound address.
    ///
    /// # Errors
    /// The socket's error.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// What was taken and dropped so far.
    #[must_use]
    pub fn stats(&self) -> RcInStats {
        self.stats
    }

    /// Read everything waiting; the last good frame, if any came. A bad datagram is dropped and counted
    /// (the first one with a warning).
    ///
    /// # Errors
    /// A socket error that is not transient.
    pub fn poll(&mut self) -> io::Result<Option<RcFrame>> {
        let mut latest = None;
        loop {
            let (n, from) = match self.socket.recv_from(&mut self.buf) {
                Ok(got) => got,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return Ok(latest),
                Err(e) if autopilot::runtime::transport::is_transient(&e) => continue,
                Err(e) => return Err(e),
            };
            match parse_rc_datagram(&self.buf[..n]) {
                Ok(frame) => {
                    self.stats.accepted += 1;
                    latest = Some(frame);
                }
                Err(e) => {
                    self.stats.dropped += 1;
                    if !self.warned {
                        self.warned = true;
                        tracing::warn!(
                            %from,
                            error = %e,
                            "RC input: datagram dropped (later bad ones are counted, not logged): send \
                             {RC_IN_MIN_CHANNELS} to {RC_IN_MAX_CHANNELS} little-endian u16 PWM values, \
                             {RC_PWM_MIN_US}..={RC_PWM_MAX_US} us"
                        );
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn le(values: &[u16]) -> Vec<u8> {
        values.iter().flat_map(|v| v.to_le_bytes()).collect()
    }

    #[test]
    fn given_8_to_16_values_in_range_then_they_are_channels_1_to_n() {
        let values: Vec<u16> = (0..16).map(|i| 1000 + 50 * i).collect();
        for n in RC_IN_MIN_CHANNELS..=RC_IN_MAX_CHANNELS {
            let frame = parse_rc_datagram(&le(&values[..n])).unwrap();
            assert_eq!(usize::from(frame.count), n);
            assert_eq!(&frame.channels_us[..n], &values[..n]);
            assert!(frame.channels_us[n..].iter().all(|&v| v == 0));
            assert_eq!(frame.channel_us(3), Some(1100), "channel 3 is the third value");
        }
        let edges = parse_rc_datagram(&le(&[800, 2200, 800, 2200, 800, 2200, 800, 2200])).unwrap();
        assert_eq!(&edges.channels_us[..2], &[800, 2200]);
    }

    #[test]
    fn given_a_bad_datagram_then_the_error_says_what_is_wrong() {
        assert_eq!(parse_rc_datagram(&[0; 17]), Err(RcDatagramError::OddLength(17)));
        assert_eq!(parse_rc_datagram(&le(&[1500; 7])), Err(RcDatagramError::Count(7)));
        assert_eq!(parse_rc_datagram(&le(&[1500; 17])), Err(RcDatagramError::Count(17)));
        assert_eq!(parse_rc_datagram(&[]), Err(RcDatagramError::Count(0)));
        let mut v = [1500_u16; 8];
        v[4] = 799;
        assert_eq!(parse_rc_datagram(&le(&v)), Err(RcDatagramError::Range { channel: 5, value_us: 799 }));
        v[4] = 2201;
        let e = parse_rc_datagram(&le(&v)).unwrap_err();
        assert_eq!(e.to_string(), "channel 5 = 2201 us is outside 800..=2200");
    }

    proptest! {
        /// Any byte string either parses to a frame whose channels are its u16 values, or is refused.
        #[test]
        fn any_bytes_parse_to_their_u16_values_or_are_refused(bytes in proptest::collection::vec(any::<u8>(), 0..40)) {
            let values: Vec<u16> = bytes.chunks(2).map(|c| u16::from_le_bytes([c[0], *c.get(1).unwrap_or(&0)])).collect();
            let good = bytes.len() % 2 == 0
                && (RC_IN_MIN_CHANNELS..=RC_IN_MAX_CHANNELS).contains(&values.len())
                && values.iter().all(|v| (RC_PWM_MIN_US..=RC_PWM_MAX_US).contains(v));
            // As the port applies it: a good datagram replaces the held frame, a bad one changes nothing.
            let held = RcFrame::of(&[1234; 9]);
            let mut radio = crate::plant::Radio::default();
            radio.set_port_frame(held);
            match parse_rc_datagram(&bytes) {
                Ok(frame) => {
                    prop_assert!(good);
                    prop_assert_eq!(usize::from(frame.count), values.len());
                    prop_assert_eq!(&frame.channels_us[..values.len()], values.as_slice());
                    prop_assert!(frame.channels_us[values.len()..].iter().all(|&v| v == 0));
                    radio.set_port_frame(frame);
                    prop_assert_eq!(radio.output(0), Some(frame));
                }
                Err(_) => {
                    prop_assert!(!good);
                    prop_assert_eq!(radio.output(0), Some(held), "a refused datagram changes nothing");
                }
            }
        }

        /// In range by construction: always a frame.
        #[test]
        fn any_8_to_16_values_in_range_parse(
            values in proptest::collection::vec(RC_PWM_MIN_US..=RC_PWM_MAX_US, 8..=16),
        ) {
            let frame = parse_rc_datagram(&le(&values)).unwrap();
            prop_assert_eq!(&frame.channels_us[..values.len()], values.as_slice());
        }
    }

    #[test]
    fn given_good_and_bad_datagrams_on_the_port_then_the_last_good_is_held_and_the_bad_counted() {
        let mut port = RcInPort::bind("127.0.0.1:0").unwrap();
        let to = port.local_addr().unwrap();
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        assert_eq!(port.poll().unwrap(), None, "nothing sent: nothing read");
        let first = [1100_u16, 1200, 1000, 1500, 1500, 1500, 1500, 1500];
        let second = [1900_u16; 10];
        tx.send_to(&le(&first), to).unwrap();
        tx.send_to(&le(&second), to).unwrap();
        tx.send_to(&le(&[1500; 20]), to).unwrap();
        tx.send_to(b"hello", to).unwrap();
        // Loopback UDP is queued at the receiver by the send itself.
        let got = port.poll().unwrap();
        assert_eq!(got, Some(RcFrame::of(&second)), "the last good frame, not a bad one after it");
        assert_eq!(port.stats(), RcInStats { accepted: 2, dropped: 2 });
        assert_eq!(port.poll().unwrap(), None, "read once");
    }
}
