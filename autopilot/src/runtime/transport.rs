//! Blocking byte transports for the plant link, shared by both ends of the plant protocol (the autopilot
//! here, the plant server in `sitl::link`): a UDP socket connected to one peer, and a serial port (the
//! real airframe's ARM board, or a pty pair in tests). In: `send` one datagram or a run of stream bytes.
//! Out: `recv` returns what arrived within the transport's poll interval ([`POLL_INTERVAL`] by default),
//! or `None`; timers (resend, link loss) are the caller's, checked after every return.
//!
//! The poll interval is fixed at open: setting a socket timeout per call would cost a system call per
//! lockstep step, and the lockstep round trip is what bounds the two-process real-time factor.
//!
//! Serial is 8N1 without flow control; a read returns as soon as any bytes are there (a piece of a
//! frame is normal: the caller's [`crate::core::mavlink::frame::FrameDecoder::push`] reassembles).

use std::io::{self, Read, Write};
use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

/// Largest datagram read.
const MAX_DATAGRAM_BYTES: usize = 65_536;

/// How long a `recv` waits for input before returning `None`.
pub const POLL_INTERVAL: Duration = Duration::from_millis(20);

/// How long a UDP `recv` polls without sleeping before it blocks. In lockstep the other end answers
/// within tens of microseconds; a receiver asleep in the kernel costs a wake-up on every datagram (on
/// this project's 2-core VM a blocking UDP round trip took 31 µs, a polling one 9 µs), one that is
/// polling does not. See [`SpinReceiver`] for when it polls at all.
pub const UDP_SPIN: Duration = Duration::from_micros(50);

/// A wait shorter than this (polling plus blocking) re-arms the polling. It is well above a blocking
/// lockstep round trip (both ends asleep: tens of µs, more on a busy machine) and well below the 2 ms of a
/// real-time plant step, so one slow round trip in lockstep does not leave both ends blocking for good.
pub const UDP_SPIN_REARM: Duration = Duration::from_micros(500);

/// Receives on a UDP socket opened non-blocking: polls for up to [`UDP_SPIN`], then blocks for up to the
/// socket's read timeout. It polls only while datagrams come quickly: after a wait longer than
/// [`UDP_SPIN_REARM`] (real-time pacing, a datagram every 2 ms) it blocks at once, until a wait is short
/// again, so a paced SITL does not burn a core polling. The socket's mode changes only when the receiver
/// switches between polling and blocking, not around every wait: paced, a receive is one blocking call
/// rather than a failed poll and two mode changes besides (of a paced autopilot's five system calls per
/// step, three).
#[derive(Debug, Clone, Copy)]
pub struct SpinReceiver {
    spin: bool,
    /// Whether this receiver last left the socket blocking.
    blocking: bool,
}

impl Default for SpinReceiver {
    fn default() -> Self {
        Self { spin: true, blocking: false }
    }
}

impl SpinReceiver {
    /// Receive with `op` (`recv`, `recv_from`); `Ok(None)` when nothing came within the read timeout.
    ///
    /// # Errors
    /// The socket's error, other than the transient ones of [`is_transient`].
    pub fn recv<T>(
        &mut self,
        socket: &UdpSocket,
        mut op: impl FnMut(&UdpSocket) -> io::Result<T>,
    ) -> io::Result<Option<T>> {
        let start = std::time::Instant::now();
        if self.spin {
            self.set_blocking(socket, false)?;
            loop {
                match op(socket) {
                    Ok(v) => return Ok(Some(v)),
                    Err(e) if is_transient(&e) => {}
                    Err(e) => return Err(e),
                }
                if start.elapsed() >= UDP_SPIN {
                    break;
                }
                std::hint::spin_loop();
            }
        }
        self.set_blocking(socket, true)?;
        let result = op(socket);
        self.spin = start.elapsed() < UDP_SPIN_REARM;
        match result {
            Ok(v) => Ok(Some(v)),
            Err(e) if is_transient(&e) => Ok(None),
            Err(e) => Err(e),
        }
    }

    fn set_blocking(&mut self, socket: &UdpSocket, blocking: bool) -> io::Result<()> {
        if self.blocking != blocking {
            socket.set_nonblocking(!blocking)?;
            self.blocking = blocking;
        }
        Ok(())
    }
}

/// Bytes in and out over one link.
pub trait Transport {
    /// Send `bytes` (one datagram, or written to the stream).
    ///
    /// # Errors
    /// The underlying I/O error.
    fn send(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Wait up to the poll interval for input: `Ok(None)` when none came.
    ///
    /// # Errors
    /// The underlying I/O error (a timeout is not an error).
    fn recv(&mut self) -> io::Result<Option<&[u8]>>;
    /// Each `recv` returns whole frames (a datagram) rather than a piece of a byte stream.
    fn is_datagram(&self) -> bool;
    /// There is a peer to send to (a listening UDP end: not before the other end's first datagram).
    fn has_peer(&self) -> bool {
        true
    }
    /// Make the sender of the last received datagram the peer (a listening UDP end); nothing for
    /// point-to-point links.
    fn adopt_last_sender(&mut self) {}
    /// What this link is, for logs and errors (`udp://127.0.0.1:4560`, `serial:/dev/ttyACM0`).
    fn describe(&self) -> String;
}

/// Whether an I/O error only means "nothing this time": a timeout, an interrupted call, or an ICMP
/// port-unreachable report for a peer not (yet or any more) listening, which the caller's link-loss
/// timer handles.
#[must_use]
pub fn is_transient(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock
            | io::ErrorKind::TimedOut
            | io::ErrorKind::Interrupted
            | io::ErrorKind::ConnectionRefused
            | io::ErrorKind::ConnectionReset
    )
}

/// A UDP socket on any local port, connected to one peer (the autopilot's end: the plant listens).
#[derive(Debug)]
pub struct UdpPeerTransport {
    socket: UdpSocket,
    peer: SocketAddr,
    receiver: SpinReceiver,
    buf: Vec<u8>,
}

impl UdpPeerTransport {
    /// Bind an ephemeral port and connect it to `peer`, with `poll` as the receive timeout.
    ///
    /// # Errors
    /// The bind, connect or socket-option error.
    pub fn connect(peer: SocketAddr, poll: Duration) -> io::Result<Self> {
        let bind: SocketAddr = if peer.is_ipv4() { ([0, 0, 0, 0], 0).into() } else { ([0u16; 8], 0).into() };
        let socket = UdpSocket::bind(bind)?;
        socket.connect(peer)?;
        socket.set_read_timeout(Some(poll.max(Duration::from_micros(1))))?;
        socket.set_nonblocking(true)?;
        Ok(Self { socket, peer, receiver: SpinReceiver::default(), buf: vec![0; MAX_DATAGRAM_BYTES] })
    }

    /// The local address.
    ///
    /// # Errors
    /// The socket's error.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }
}

impl Transport for UdpPeerTransport {
    /// A peer not listening yet is not an error here: the datagram is lost and the caller retries.
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        match self.socket.send(bytes) {
            Ok(_) => Ok(()),
            Err(e) if is_transient(&e) => Ok(()),
            Err(e) => Err(e),
        }
    }

    fn recv(&mut self) -> io::Result<Option<&[u8]>> {
        let buf = &mut self.buf;
        let n = self.receiver.recv(&self.socket, |s| s.recv(buf))?;
        Ok(n.map(|n| &self.buf[..n]))
    }

    fn is_datagram(&self) -> bool {
        true
    }

    fn describe(&self) -> String {
        format!("udp://{}", self.peer)
    }
}

/// A serial port (8N1, no flow control): a byte stream.
pub struct SerialTransport {
    port: Box<dyn serialport::SerialPort>,
    path: String,
    buf: Vec<u8>,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport").field("path", &self.path).finish_non_exhaustive()
    }
}

impl SerialTransport {
    /// Open `path` at `baud_rate` with `poll` as the read timeout.
    ///
    /// # Errors
    /// The open error, as an I/O error.
    pub fn open(path: &str, baud_rate: u32, poll: Duration) -> io::Result<Self> {
        let port = serialport::new(path, baud_rate)
            .timeout(poll.max(Duration::from_millis(1)))
            .open()
            .map_err(io::Error::from)?;
        Ok(Self { port, path: path.to_owned(), buf: vec![0; 4096] })
    }
}

impl SerialTransport {
    /// How long the next read (or write) may wait: a ground-station link sets it before each call, to the
    /// time its pacer next has a frame to write (it costs no system call).
    ///
    /// # Errors
    /// The port's error.
    pub fn set_timeout(&mut self, timeout: Duration) -> io::Result<()> {
        self.port.set_timeout(timeout).map_err(io::Error::from)
    }

    /// Writes `bytes` without waiting for them to leave the UART (no `tcdrain`, which at 57600 baud
    /// blocks for the frame's transmission): for a writer that paces itself.
    ///
    /// # Errors
    /// The write error (a timeout when the port's buffer stays full).
    pub fn write_unflushed(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)
    }
}

impl Transport for SerialTransport {
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn recv(&mut self) -> io::Result<Option<&[u8]>> {
        match self.port.read(&mut self.buf) {
            Ok(0) => Ok(None),
            Ok(n) => Ok(Some(&self.buf[..n])),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
                ) =>
            {
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    fn is_datagram(&self) -> bool {
        false
    }

    fn describe(&self) -> String {
        format!("serial:{}", self.path)
    }
}

/// Where a serial device is: `DEVICE:BAUD` (e.g. `/dev/ttyACM0:921600`), the device possibly holding
/// colons itself (the baud rate is after the last one).
///
/// # Errors
/// A message naming what is wrong.
pub fn parse_serial_spec(spec: &str) -> Result<(String, u32), String> {
    let (device, baud) = spec.rsplit_once(':').ok_or_else(|| format!("`{spec}` is not DEVICE:BAUD"))?;
    if device.is_empty() {
        return Err(format!("`{spec}` names no device"));
    }
    let baud: u32 = baud.parse().map_err(|_| format!("baud rate `{baud}` in `{spec}` is not a whole number"))?;
    if baud == 0 {
        return Err(format!("baud rate 0 in `{spec}`"));
    }
    Ok((device.to_owned(), baud))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn serial_specs_parse_and_bad_ones_say_why() {
        assert_eq!(parse_serial_spec("/dev/ttyACM0:921600"), Ok(("/dev/ttyACM0".into(), 921_600)));
        assert_eq!(
            parse_serial_spec("/dev/serial/by-id/usb-a:b-if00:57600"),
            Ok(("/dev/serial/by-id/usb-a:b-if00".into(), 57_600))
        );
        assert!(parse_serial_spec("/dev/ttyACM0").unwrap_err().contains("DEVICE:BAUD"));
        assert!(parse_serial_spec(":57600").unwrap_err().contains("no device"));
        assert!(parse_serial_spec("/dev/x:fast").unwrap_err().contains("not a whole number"));
        assert!(parse_serial_spec("/dev/x:0").unwrap_err().contains("baud rate 0"));
    }

    #[test]
    fn udp_peer_transport_exchanges_datagrams_and_times_out_quietly() {
        let peer = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let mut t =
            UdpPeerTransport::connect(peer.local_addr().expect("addr"), Duration::from_millis(5)).expect("connect");
        assert_eq!(t.recv().expect("timeout is not an error"), None);
        t.send(b"ping").expect("send");
        let mut buf = [0u8; 16];
        let (n, from) = peer.recv_from(&mut buf).expect("recv");
        assert_eq!(&buf[..n], b"ping");
        peer.send_to(b"pong", from).expect("reply");
        assert_eq!(t.recv().expect("recv"), Some(&b"pong"[..]));
        assert!(t.describe().starts_with("udp://127.0.0.1:"));
    }

    #[test]
    fn udp_peer_transport_to_nobody_is_quiet_not_an_error() {
        let gone = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let addr = gone.local_addr().expect("addr");
        drop(gone);
        let mut t = UdpPeerTransport::connect(addr, Duration::from_millis(5)).expect("connect");
        t.send(b"anyone?").expect("nobody listening is not an error");
        assert_eq!(t.recv().expect("the ICMP report is swallowed"), None);
    }
}
