//! The TCP ground-station link: a server on `0.0.0.0:5760 + N` for instance N (ArduPilot's and PX4's
//! SITL TCP port; configurable) accepting up to [`TcpConfig::max_clients`] clients at once (default
//! [`MAX_TCP_CLIENTS`]; one more is closed at once, and a burst of refusals is logged once). In: each client's byte stream through
//! its own stream decoder; each valid frame goes to the core as an [`Incoming`] tagged with the client's
//! address. Out: each [`Outgoing`] is encoded once and queued to every connected client
//! ([`Destination::All`]) or to one ([`Destination::Peer`]).
//!
//! One task accepts and routes; one task per client reads and writes. A client that disconnects, fails or
//! falls [`CLIENT_QUEUE_FRAMES`] frames behind is dropped without disturbing the others (its frames
//! dropped are counted as send errors). Only a listener failure that is not about one connection stops
//! the link, as a [`LinkError`].

use std::collections::BTreeMap;
use std::io::ErrorKind;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::sync::Arc;

use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TrySendError;
use tokio::task::JoinSet;

use super::frame::{CountingDecoder, LinkCounters};
use super::link::{Destination, Incoming, LinkError, LinkId, Outgoing, deliver};
use super::ports::InstancePorts;
use super::shutdown::Shutdown;
use super::signing::LinkSigning;

/// Frames queued to one client before it counts as stalled and its frames are dropped.
pub const CLIENT_QUEUE_FRAMES: usize = 256;
/// The default of [`TcpConfig::max_clients`]: the most clients served at once; a connection beyond it is
/// closed at once, so idle connections cannot exhaust the process.
pub const MAX_TCP_CLIENTS: usize = 16;
/// Read size per client, in bytes.
const READ_CHUNK_BYTES: usize = 4096;

/// Where the TCP server listens.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TcpConfig {
    /// This link's id (its index in the runtime's link list).
    pub link: LinkId,
    /// Local address to listen on (port 0 picks a free one, for tests).
    pub bind: SocketAddr,
    /// The most clients served at once ([`MAX_TCP_CLIENTS`] by default); `[gcs] tcp_max_clients`.
    pub max_clients: usize,
}

impl TcpConfig {
    /// `0.0.0.0:5760 + N` for an instance ([`InstancePorts`]).
    #[must_use]
    pub fn for_ports(ports: &InstancePorts) -> Self {
        Self {
            link: 1,
            bind: SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, ports.tcp)),
            max_clients: MAX_TCP_CLIENTS,
        }
    }
}

impl Default for TcpConfig {
    fn default() -> Self {
        Self::for_ports(&InstancePorts::FIRST)
    }
}

/// A listening TCP link, ready to [`TcpLink::run`].
#[derive(Debug)]
pub struct TcpLink {
    link: LinkId,
    listener: TcpListener,
    local: SocketAddr,
    max_clients: usize,
    counters: Arc<LinkCounters>,
    signing: Arc<LinkSigning>,
}

type Frame = Arc<[u8]>;

impl TcpLink {
    /// Start listening.
    ///
    /// # Errors
    /// [`LinkError::Bind`] if the address cannot be bound, [`LinkError::Io`] if its local address cannot
    /// be read back.
    pub async fn bind(config: TcpConfig) -> Result<Self, LinkError> {
        let listener =
            TcpListener::bind(config.bind).await.map_err(|source| LinkError::Bind { addr: config.bind, source })?;
        let local = listener.local_addr()?;
        tracing::info!(%local, "TCP ground-station link listening");
        Ok(Self {
            link: config.link,
            listener,
            local,
            max_clients: config.max_clients,
            counters: LinkCounters::new_shared(),
            signing: Arc::default(),
        })
    }

    /// Signs and verifies with the process's shared signing state (default: its own, off).
    #[must_use]
    pub fn with_signing(mut self, signing: Arc<LinkSigning>) -> Self {
        self.signing = signing;
        self
    }

    /// The listening address (with the real port when bound to port 0).
    #[must_use]
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// The link's counters (all clients together).
    #[must_use]
    pub fn counters(&self) -> Arc<LinkCounters> {
        self.counters.clone()
    }

    /// Accept clients and move frames until shutdown fires or the core closes `outgoing`; then every client
    /// task is ended and awaited, and the `incoming` senders are dropped.
    ///
    /// # Errors
    /// [`LinkError::Receive`] when accepting fails in a way that is not about one connection.
    pub async fn run(
        self,
        incoming: mpsc::Sender<Incoming>,
        mut outgoing: mpsc::Receiver<Outgoing>,
        mut shutdown: Shutdown,
    ) -> Result<(), LinkError> {
        let mut clients: BTreeMap<SocketAddr, ClientQueue> = BTreeMap::new();
        let mut tasks = JoinSet::new();
        let mut refusals = Refusals::default();
        let result = loop {
            tokio::select! {
                biased;
                () = shutdown.recv() => break Ok(()),
                Some(done) = tasks.join_next(), if !tasks.is_empty() => {
                    match done {
                        Ok(peer) => {
                            clients.remove(&peer);
                            let _logged = refusals.slot_freed(self.max_clients);
                        }
                        Err(e) => tracing::error!(error = %e, "TCP client task panicked"),
                    }
                }
                out = outgoing.recv() => {
                    let Some(out) = out else { break Ok(()) };
                    self.route(&mut clients, &out);
                }
                accepted = self.listener.accept() => match accepted {
                    Ok((stream, peer)) if clients.len() >= self.max_clients => {
                        let _logged = refusals.refused(peer, self.max_clients);
                        drop(stream);
                    }
                    Ok((stream, peer)) => {
                        tracing::info!(%peer, "TCP ground-station client connected");
                        let (tx, rx) = mpsc::channel(CLIENT_QUEUE_FRAMES);
                        clients.insert(peer, ClientQueue { tx, stalled: false });
                        let client = Client {
                            link: self.link,
                            peer,
                            incoming: incoming.clone(),
                            outgoing: rx,
                            shutdown: shutdown.clone(),
                            counters: self.counters.clone(),
                            signing: self.signing.clone(),
                        };
                        tasks.spawn(client.run(stream));
                    }
                    Err(e) if is_per_connection(&e) => {
                        tracing::warn!(error = %e, "TCP accept failed for one connection");
                    }
                    Err(source) => break Err(LinkError::Receive { local: self.local, source }),
                }
            }
        };
        // Drain: closing each client's queue ends its task (a task in a shutdown select ends anyway).
        drop(clients);
        drop(incoming);
        while let Some(done) = tasks.join_next().await {
            if let Err(e) = done {
                tracing::error!(error = %e, "TCP client task panicked");
            }
        }
        tracing::info!(local = %self.local, "TCP ground-station link stopped");
        result
    }

    fn route(&self, clients: &mut BTreeMap<SocketAddr, ClientQueue>, out: &Outgoing) {
        let frame: Frame = self.signing.encode(out.header, &out.message).into();
        let mut gone = Vec::new();
        for (peer, ClientQueue { tx, stalled }) in clients.iter_mut() {
            if let Destination::Peer(to) = out.to
                && to != *peer
            {
                continue;
            }
            match tx.try_send(frame.clone()) {
                Ok(()) => {
                    if std::mem::take(stalled) {
                        tracing::info!(%peer, "TCP client reading again");
                    }
                }
                Err(TrySendError::Full(_)) => {
                    self.counters.add_send_error();
                    if !std::mem::replace(stalled, true) {
                        tracing::warn!(%peer, "TCP client is not reading; its frames are dropped until it reads");
                    }
                }
                Err(TrySendError::Closed(_)) => gone.push(*peer),
            }
        }
        if let Destination::Peer(to) = out.to
            && !clients.contains_key(&to)
        {
            self.counters.add_send_error();
            tracing::debug!(peer = %to, "reply to a TCP client that is not connected dropped");
        }
        for peer in gone {
            clients.remove(&peer);
        }
    }
}

/// The queue to one client's task, and whether it is full (said once per stall, not per frame dropped).
struct ClientQueue {
    tx: mpsc::Sender<Frame>,
    stalled: bool,
}

/// The refusals of one burst: while the server is full, the first refused connection is logged (with the
/// cap) and the rest only counted; when a client leaves, how many were refused is logged and the next
/// burst starts. A thousand connection attempts make two log lines, not a thousand.
#[derive(Debug, Default)]
struct Refusals {
    in_burst: u64,
    total: u64,
}

impl Refusals {
    /// One connection refused; true if this one was logged (the first of its burst).
    fn refused(&mut self, peer: SocketAddr, max: usize) -> bool {
        let first = self.in_burst == 0;
        if first {
            tracing::warn!(%peer, max, "TCP client cap reached: refusing new clients until one leaves");
        }
        self.in_burst += 1;
        self.total += 1;
        first
    }

    /// A client left; true if that ended a burst of refusals (and it was logged).
    fn slot_freed(&mut self, max: usize) -> bool {
        let ended = self.in_burst > 0;
        if ended {
            tracing::info!(refused = self.in_burst, total_refused = self.total, max, "TCP client slot free again");
            self.in_burst = 0;
        }
        ended
    }
}

/// Accept errors that concern one incoming connection, not the listener.
fn is_per_connection(e: &std::io::Error) -> bool {
    matches!(e.kind(), ErrorKind::ConnectionAborted | ErrorKind::ConnectionReset | ErrorKind::ConnectionRefused)
}

/// One connected client's task state.
struct Client {
    link: LinkId,
    peer: SocketAddr,
    incoming: mpsc::Sender<Incoming>,
    outgoing: mpsc::Receiver<Frame>,
    shutdown: Shutdown,
    counters: Arc<LinkCounters>,
    signing: Arc<LinkSigning>,
}

impl Client {
    /// Read and write until the client leaves, fails, the server drops its queue, or shutdown; returns the
    /// peer so the server can forget it. Errors end only this client and are logged with its address.
    async fn run(mut self, stream: TcpStream) -> SocketAddr {
        let peer = self.peer;
        let (mut reader, mut writer) = stream.into_split();
        let mut decoder = CountingDecoder::new(self.counters.clone());
        let mut buf = vec![0u8; READ_CHUNK_BYTES];
        loop {
            tokio::select! {
                biased;
                () = self.shutdown.recv() => break,
                frame = self.outgoing.recv() => {
                    let Some(frame) = frame else { break };
                    if let Err(e) = writer.write_all(&frame).await {
                        self.counters.add_send_error();
                        tracing::warn!(%peer, error = %e, "TCP client write failed; dropping the client");
                        break;
                    }
                    self.counters.add_sent(frame.len());
                }
                read = reader.read(&mut buf) => match read {
                    Ok(0) => {
                        let _ = decoder.finish();
                        tracing::info!(%peer, "TCP ground-station client disconnected");
                        break;
                    }
                    Ok(n) => {
                        let frames = self.signing.verify(decoder.push(&buf[..n]), &self.counters);
                        if !deliver(&self.incoming, &self.counters, self.link, peer, frames) {
                            return peer;
                        }
                    }
                    Err(e) => {
                        tracing::warn!(%peer, error = %e, "TCP client read failed; dropping the client");
                        break;
                    }
                }
            }
        }
        peer
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::runtime::frame::encode_v2;
    use crate::runtime::frame::tests::heartbeat;
    use crate::runtime::frame::{DecodedFrame, FrameDecoder};
    use crate::runtime::link::CHANNEL_CAPACITY;
    use crate::runtime::shutdown::{self, ShutdownTrigger};
    use mavlink::MavHeader;
    use mavlink::dialects::common::MavMessage;
    use std::time::Duration;
    use tokio::task::JoinHandle;

    const WAIT: Duration = Duration::from_secs(2);
    const QUIET: Duration = Duration::from_millis(200);

    struct Harness {
        addr: SocketAddr,
        incoming: mpsc::Receiver<Incoming>,
        outgoing: mpsc::Sender<Outgoing>,
        trigger: ShutdownTrigger,
        task: JoinHandle<Result<(), LinkError>>,
    }

    async fn start() -> Harness {
        let link = TcpLink::bind(TcpConfig {
            link: 1,
            bind: "127.0.0.1:0".parse().expect("addr"),
            max_clients: MAX_TCP_CLIENTS,
        })
        .await
        .expect("bind");
        let addr = link.local_addr();
        let (in_tx, incoming) = mpsc::channel(CHANNEL_CAPACITY);
        let (outgoing, out_rx) = mpsc::channel(CHANNEL_CAPACITY);
        let (trigger, shutdown) = shutdown::channel();
        let task = tokio::spawn(link.run(in_tx, out_rx, shutdown));
        Harness { addr, incoming, outgoing, trigger, task }
    }

    /// A connected client whose hello heartbeat the core has seen (so the server has registered it).
    async fn connect(h: &mut Harness) -> TcpStream {
        let mut s = TcpStream::connect(h.addr).await.expect("connect");
        let (hh, hm) = heartbeat(255, 0);
        s.write_all(&encode_v2(hh, &hm)).await.expect("write");
        let got = tokio::time::timeout(WAIT, h.incoming.recv()).await.expect("in time").expect("alive");
        assert_eq!(got.peer, s.local_addr().expect("addr"), "frames arrive with the client's address");
        assert_eq!(got.message, hm);
        s
    }

    async fn next_frame(s: &mut TcpStream, dec: &mut FrameDecoder, wait: Duration) -> Option<DecodedFrame> {
        let mut buf = [0u8; 512];
        loop {
            let n = tokio::time::timeout(wait, s.read(&mut buf)).await.ok()?.expect("read");
            if n == 0 {
                return None;
            }
            if let Some(f) = dec.push(&buf[..n]).into_iter().next() {
                return Some(f);
            }
        }
    }

    async fn broadcast(h: &Harness, seq: u8) {
        let (_, message) = heartbeat(1, seq);
        let header = MavHeader { system_id: 1, component_id: 1, sequence: seq };
        h.outgoing.send(Outgoing { to: Destination::All, header, message }).await.expect("alive");
    }

    #[tokio::test]
    async fn two_clients_receive_broadcasts_and_a_disconnect_leaves_the_other() {
        let mut h = start().await;
        let mut a = connect(&mut h).await;
        let mut b = connect(&mut h).await;
        let (mut da, mut db) = (FrameDecoder::new(), FrameDecoder::new());
        for seq in 0..3 {
            broadcast(&h, seq).await;
            assert_eq!(next_frame(&mut a, &mut da, WAIT).await.expect("a").header.sequence, seq);
            assert_eq!(next_frame(&mut b, &mut db, WAIT).await.expect("b").header.sequence, seq);
        }
        drop(a);
        // Give the server a moment to see the EOF; the broadcast must reach b whether or not it has.
        tokio::time::sleep(Duration::from_millis(50)).await;
        for seq in 3..6 {
            broadcast(&h, seq).await;
            assert_eq!(next_frame(&mut b, &mut db, WAIT).await.expect("b after a left").header.sequence, seq);
        }
        // b still talks to the core.
        let (hh, hm) = heartbeat(255, 9);
        b.write_all(&encode_v2(hh, &hm)).await.expect("write");
        let got = tokio::time::timeout(WAIT, h.incoming.recv()).await.expect("in time").expect("alive");
        assert_eq!((got.peer, got.header.sequence), (b.local_addr().expect("addr"), 9));
    }

    #[tokio::test]
    async fn a_reply_reaches_only_its_client_and_split_frames_are_joined() {
        let mut h = start().await;
        let mut a = connect(&mut h).await;
        let mut b = connect(&mut h).await;
        // A frame written in two pieces with garbage before it still arrives once.
        let (hh, hm) = heartbeat(255, 4);
        let bytes = encode_v2(hh, &hm);
        a.write_all(&[0x55, 0xAA]).await.expect("write");
        a.write_all(&bytes[..5]).await.expect("write");
        tokio::time::sleep(Duration::from_millis(20)).await;
        a.write_all(&bytes[5..]).await.expect("write");
        let got = tokio::time::timeout(WAIT, h.incoming.recv()).await.expect("in time").expect("alive");
        assert_eq!(got.header.sequence, 4);
        let (_, message) = heartbeat(1, 0);
        let to = Destination::Peer(a.local_addr().expect("addr"));
        let header = MavHeader { system_id: 1, component_id: 1, sequence: 42 };
        h.outgoing.send(Outgoing { to, header, message }).await.expect("alive");
        let (mut da, mut db) = (FrameDecoder::new(), FrameDecoder::new());
        assert_eq!(next_frame(&mut a, &mut da, WAIT).await.expect("a").header.sequence, 42);
        assert!(next_frame(&mut b, &mut db, QUIET).await.is_none(), "b gets nothing");
        assert!(matches!(got.message, MavMessage::HEARTBEAT(_)));
    }

    #[tokio::test]
    async fn shutdown_ends_server_and_clients_promptly() {
        let mut h = start().await;
        let mut a = connect(&mut h).await;
        h.trigger.fire();
        let res = tokio::time::timeout(WAIT, h.task).await.expect("ends promptly").expect("no panic");
        assert!(res.is_ok());
        assert!(h.incoming.recv().await.is_none(), "every incoming sender dropped");
        let mut buf = [0u8; 16];
        let n = tokio::time::timeout(WAIT, a.read(&mut buf)).await.expect("closed promptly");
        assert!(matches!(n, Ok(0) | Err(_)), "the client sees the connection end: {n:?}");
    }

    #[test]
    fn a_burst_of_refusals_is_logged_once_and_its_end_once() {
        let mut r = Refusals::default();
        let peer: SocketAddr = "127.0.0.1:9".parse().expect("addr");
        let logged = (0..1000).filter(|_| r.refused(peer, 16)).count();
        assert_eq!(logged, 1);
        assert!(r.slot_freed(16), "the end of the burst is said");
        assert!(!r.slot_freed(16), "a client leaving without refusals says nothing");
        assert!(r.refused(peer, 16), "a new burst is said again");
        assert_eq!(r.total, 1001);
    }

    #[test]
    fn instance_shifts_the_port() {
        assert_eq!(
            TcpConfig::for_ports(&InstancePorts::of(3).expect("in range")).bind,
            "0.0.0.0:5763".parse().expect("addr")
        );
    }

    #[tokio::test]
    async fn a_connection_beyond_the_client_cap_is_closed_and_the_others_are_served() {
        let mut h = start().await;
        let mut clients = Vec::new();
        for _ in 0..MAX_TCP_CLIENTS {
            clients.push(connect(&mut h).await);
        }
        // One more: closed at once (its read sees the end of the stream).
        let mut extra = TcpStream::connect(h.addr).await.expect("connect");
        let mut buf = [0u8; 16];
        let n = tokio::time::timeout(WAIT, extra.read(&mut buf)).await.expect("closed in time").unwrap_or(0);
        assert_eq!(n, 0, "the extra connection is closed");
        // The others still get broadcasts.
        broadcast(&h, 5).await;
        let mut dec = FrameDecoder::new();
        assert!(next_frame(&mut clients[0], &mut dec, WAIT).await.is_some());
        h.trigger.fire();
        h.task.await.expect("join").expect("ok");
    }
}
