//! The plant link over UDP: the plant's socket, bound to its port, sending to the autopilot that spoke
//! last (as PX4's simulator interface: the plant listens, the autopilot announces itself).

use std::io;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::Duration;

use autopilot::runtime::transport::{POLL_INTERVAL, SpinReceiver, Transport, is_transient};

/// UDP: bound to the plant's port, sending to the autopilot that spoke last.
#[derive(Debug)]
pub struct UdpTransport {
    socket: UdpSocket,
    local: SocketAddr,
    peer: Option<SocketAddr>,
    last_sender: Option<SocketAddr>,
    receiver: SpinReceiver,
    buf: Vec<u8>,
}

impl UdpTransport {
    /// Bind `addr` (e.g. `127.0.0.1:4560`, or port 0 in tests); no peer until one speaks. A `recv` polls
    /// for [`UDP_SPIN`](autopilot::runtime::transport::UDP_SPIN), then waits at most [`POLL_INTERVAL`].
    ///
    /// # Errors
    /// The bind or socket-option error.
    pub fn bind(addr: impl ToSocketAddrs) -> io::Result<Self> {
        let socket = UdpSocket::bind(addr)?;
        socket.set_read_timeout(Some(POLL_INTERVAL))?;
        socket.set_nonblocking(true)?;
        let local = socket.local_addr()?;
        Ok(Self {
            socket,
            local,
            peer: None,
            last_sender: None,
            receiver: SpinReceiver::default(),
            buf: vec![0; 65_536],
        })
    }

    /// Wait at most `poll` in a `recv` instead of [`POLL_INTERVAL`] (a free-running plant steps on its own
    /// clock and must not sleep past a step).
    ///
    /// # Errors
    /// The socket-option error.
    pub fn with_poll(self, poll: Duration) -> io::Result<Self> {
        self.socket.set_read_timeout(Some(poll.max(Duration::from_micros(100))))?;
        Ok(self)
    }

    /// Send to `peer` from the start instead of waiting for it to speak.
    #[must_use]
    pub fn with_peer(mut self, peer: SocketAddr) -> Self {
        self.peer = Some(peer);
        self
    }

    /// The bound address.
    ///
    /// # Errors
    /// The socket's error.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// The autopilot's address, once known.
    #[must_use]
    pub fn peer(&self) -> Option<SocketAddr> {
        self.peer
    }
}

impl Transport for UdpTransport {
    /// Nothing to send to before the autopilot spoke; an autopilot gone away is not an error here (the
    /// link-loss timer reports it).
    fn send(&mut self, bytes: &[u8]) -> io::Result<()> {
        let Some(peer) = self.peer else { return Ok(()) };
        match self.socket.send_to(bytes, peer) {
            Ok(_) => Ok(()),
            Err(e) if is_transient(&e) => Ok(()),
            Err(e) => Err(e),
        }
    }

    /// A port-unreachable report (Windows: `ConnectionReset`) for an autopilot not yet or no longer
    /// listening is read as "nothing received": the resend and link-loss timers handle it.
    fn recv(&mut self) -> io::Result<Option<&[u8]>> {
        let buf = &mut self.buf;
        let Some((n, from)) = self.receiver.recv(&self.socket, |s| s.recv_from(buf))? else {
            return Ok(None);
        };
        self.last_sender = Some(from);
        Ok(Some(&self.buf[..n]))
    }

    fn is_datagram(&self) -> bool {
        true
    }

    fn has_peer(&self) -> bool {
        self.peer.is_some()
    }

    fn adopt_last_sender(&mut self) {
        if self.last_sender.is_some() {
            self.peer = self.last_sender;
        }
    }

    fn describe(&self) -> String {
        format!("udp://{}", self.local)
    }
}
