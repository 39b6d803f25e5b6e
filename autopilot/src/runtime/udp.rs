//! The UDP ground-station link, PX4 SITL style. One socket, bound on `0.0.0.0:18570 + N` for instance N
//! (PX4's SITL GCS port; configurable). In: datagrams from any address; each valid frame goes to the core
//! as an [`Incoming`] tagged with its sender, and the sender enters the [`PeerTable`]. Out: each
//! [`Outgoing`] is encoded once as MAVLink 2 and sent to every fixed target (127.0.0.1:14550 for
//! QGroundControl, shared by every instance, and the instance's API port 127.0.0.1:14540 + N for MAVSDK and
//! scripts; [`super::ports`]) and every live peer, or to one peer for a reply.
//!
//! Peers expire after [`PEER_EXPIRY`] (10 s) without a valid frame from them: GCS heartbeats come at 1 Hz
//! and clients give up on a silent vehicle after 3-3.5 s, so 10 s keeps a client through a few lost
//! heartbeats and a one-shot script for a while after its last message. Fixed targets never expire. At
//! most [`UdpConfig::max_peers`] peers (default [`MAX_UDP_PEERS`]) are live at once; a new sender beyond
//! that is answered but not broadcast to, and a burst of such refusals is logged once.
//! rust-mavlink's `udpin` answers only the last sender, which is why this shell keeps its own socket.
//!
//! With a data rate (`[gcs] udp_data_rate`, bytes/s; 0 by default: unlimited) the socket's output goes
//! through one [`LinkGovernor`] (`core::mavlink::link_rate`), as the serial link's does: priority messages
//! first, transfers in order, the streams thinned by PX4's rate multiplier, the bytes paced; a broadcast
//! counts its frame once per destination. A RADIO_STATUS received on the socket feeds it too. Frames are
//! then numbered by the link.
//!
//! Malformed datagrams are counted in the link's `LinkStats` and dropped; a send that fails (nobody
//! listening, full buffer) is counted and the link keeps running. Only a receive error that is not about
//! one peer stops the link, as a [`LinkError`].

use std::collections::{BTreeMap, HashSet};
use std::io::ErrorKind;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use std::sync::Arc;
use std::time::Duration;

use tokio::net::UdpSocket;
use tokio::sync::mpsc;
use tokio::time::Instant;

use super::frame::{CountingDecoder, LinkCounters};
use super::link::{Destination, GovernedOutput, Incoming, LinkError, LinkId, Outgoing, deliver};
use super::ports::InstancePorts;
use super::shutdown::Shutdown;
use super::signing::LinkSigning;

/// How long a peer stays in the table without sending a valid frame.
pub const PEER_EXPIRY: Duration = Duration::from_secs(10);
/// Largest UDP payload, in bytes: a datagram may hold several frames.
const MAX_DATAGRAM_BYTES: usize = 65_536;
/// Messages taken from the core's queue at once.
const MAX_BATCH: usize = 256;

/// Where the UDP link binds and what it always sends to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UdpConfig {
    /// This link's id (its index in the runtime's link list).
    pub link: LinkId,
    /// Local address to bind (port 0 picks a free one, for tests).
    pub bind: SocketAddr,
    /// Fixed targets: sent every broadcast, never expire.
    pub targets: Vec<SocketAddr>,
    /// How long a peer stays without traffic.
    pub peer_expiry: Duration,
    /// The most live peers at once ([`MAX_UDP_PEERS`] by default); `[gcs] udp_max_peers`.
    pub max_peers: usize,
    /// Whether this link may carry a SETUP_SIGNING (`[gcs] udp_secure`): false by default, since anyone
    /// on the network reaches a UDP port; only for a network the user trusts (see `runtime::signing`).
    pub secure: bool,
    /// Bytes/s everything the socket sends is fitted to (`[gcs] udp_data_rate`); 0 (the default):
    /// unlimited, every message sent as it comes.
    pub data_rate: u64,
}

impl UdpConfig {
    /// PX4 SITL's layout for an instance ([`InstancePorts`]): bind 0.0.0.0:18570+N, send to QGroundControl
    /// on 127.0.0.1:14550 (every instance) and to the instance's API port 127.0.0.1:14540+N.
    #[must_use]
    pub fn for_ports(ports: &InstancePorts) -> Self {
        let local = |port: u16| SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::LOCALHOST, port));
        Self {
            link: 0,
            bind: SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::UNSPECIFIED, ports.autopilot_udp)),
            targets: vec![local(ports.qgc_udp), local(ports.api_udp)],
            peer_expiry: PEER_EXPIRY,
            max_peers: MAX_UDP_PEERS,
            secure: false,
            data_rate: 0,
        }
    }
}

impl Default for UdpConfig {
    fn default() -> Self {
        Self::for_ports(&InstancePorts::FIRST)
    }
}

/// The default of [`UdpConfig::max_peers`], the most live UDP peers a link broadcasts to: a flood of
/// senders from new addresses cannot grow the table (and every broadcast) without bound. A sender beyond
/// it still gets its replies.
pub const MAX_UDP_PEERS: usize = 32;

/// Fixed targets plus every address that sent a valid frame within the expiry time (at most `max_peers`
/// of them).
#[derive(Debug, Clone)]
pub struct PeerTable {
    fixed: Vec<SocketAddr>,
    last_heard: BTreeMap<SocketAddr, Instant>,
    expiry: Duration,
    max_peers: usize,
    /// New peers not taken because the table was full.
    refused: u64,
    /// Of them, since the table last had room (the burst that was logged once).
    refused_in_burst: u64,
}

impl PeerTable {
    /// Fixed targets `fixed`, peers expiring after `expiry`, at most `max_peers` live ones.
    #[must_use]
    pub fn new(fixed: Vec<SocketAddr>, expiry: Duration, max_peers: usize) -> Self {
        Self { fixed, last_heard: BTreeMap::new(), expiry, max_peers, refused: 0, refused_in_burst: 0 }
    }

    /// `peer` sent a valid frame at `now`; true if it was not live before. A new peer while `max_peers`
    /// are live is not taken (and counted in [`PeerTable::refused`]); the first of a burst is logged.
    pub fn heard(&mut self, peer: SocketAddr, now: Instant) -> bool {
        if !self.last_heard.contains_key(&peer) && self.last_heard.len() >= self.max_peers {
            if self.refused_in_burst == 0 {
                tracing::warn!(
                    %peer,
                    max = self.max_peers,
                    "UDP peer cap reached: new senders are answered but not broadcast to until a peer expires"
                );
            }
            self.refused += 1;
            self.refused_in_burst += 1;
            return false;
        }
        self.last_heard.insert(peer, now).is_none_or(|last| now.duration_since(last) >= self.expiry)
    }

    /// New peers refused because the table was full, so far.
    #[must_use]
    pub fn refused(&self) -> u64 {
        self.refused
    }

    /// Drop peers silent for the expiry time or longer; returns them.
    pub fn expire(&mut self, now: Instant) -> Vec<SocketAddr> {
        let expiry = self.expiry;
        let mut gone = Vec::new();
        self.last_heard.retain(|peer, last| {
            let live = now.duration_since(*last) < expiry;
            if !live {
                gone.push(*peer);
            }
            live
        });
        if !gone.is_empty() && self.refused_in_burst > 0 {
            tracing::info!(refused = self.refused_in_burst, total_refused = self.refused, "UDP peer slot free again");
            self.refused_in_burst = 0;
        }
        gone
    }

    /// Live peers (after [`PeerTable::expire`]), in address order.
    pub fn peers(&self) -> impl Iterator<Item = SocketAddr> + '_ {
        self.last_heard.keys().copied()
    }

    /// Where a broadcast goes: fixed targets, then live peers not among them; no address twice.
    #[must_use]
    pub fn broadcast_targets(&self) -> Vec<SocketAddr> {
        let mut seen = HashSet::new();
        self.fixed.iter().copied().chain(self.peers()).filter(|a| seen.insert(*a)).collect()
    }
}

/// A bound UDP link, ready to [`UdpLink::run`].
#[derive(Debug)]
pub struct UdpLink {
    link: LinkId,
    socket: UdpSocket,
    local: SocketAddr,
    peers: PeerTable,
    counters: Arc<LinkCounters>,
    signing: Arc<LinkSigning>,
    /// With a data rate: the output fitted to it.
    governor: Option<GovernedOutput>,
}

impl UdpLink {
    /// Bind the socket.
    ///
    /// # Errors
    /// [`LinkError::Bind`] if the address cannot be bound, [`LinkError::Io`] if its local address cannot
    /// be read back.
    pub async fn bind(config: UdpConfig) -> Result<Self, LinkError> {
        let socket =
            UdpSocket::bind(config.bind).await.map_err(|source| LinkError::Bind { addr: config.bind, source })?;
        let local = socket.local_addr()?;
        tracing::info!(%local, targets = ?config.targets, data_rate = config.data_rate, "UDP ground-station link bound");
        let governor = (config.data_rate > 0).then(|| GovernedOutput::new(config.data_rate));
        Ok(Self {
            link: config.link,
            socket,
            local,
            peers: PeerTable::new(config.targets, config.peer_expiry, config.max_peers),
            counters: LinkCounters::new_shared(),
            signing: Arc::default(),
            governor,
        })
    }

    /// Signs and verifies with the process's shared signing state (default: its own, off).
    #[must_use]
    pub fn with_signing(mut self, signing: Arc<LinkSigning>) -> Self {
        self.signing = signing;
        self
    }

    /// The bound address (with the real port when bound to port 0).
    #[must_use]
    pub fn local_addr(&self) -> SocketAddr {
        self.local
    }

    /// The link's counters; keep a clone to read them while it runs.
    #[must_use]
    pub fn counters(&self) -> Arc<LinkCounters> {
        self.counters.clone()
    }

    /// Move frames until shutdown fires, the core drops its receiver of `incoming`, or the core closes
    /// `outgoing`. On return the `incoming` sender is dropped, so the core sees the link end.
    ///
    /// # Errors
    /// [`LinkError::Receive`] when the socket fails in a way that is not about one peer.
    pub async fn run(
        mut self,
        incoming: mpsc::Sender<Incoming>,
        mut outgoing: mpsc::Receiver<Outgoing>,
        mut shutdown: Shutdown,
    ) -> Result<(), LinkError> {
        let mut decoder = CountingDecoder::new(self.counters.clone());
        let mut buf = vec![0u8; MAX_DATAGRAM_BYTES];
        loop {
            let next = self.governor.as_mut().and_then(GovernedOutput::next_ready_in);
            let paced = async {
                match next {
                    Some(wait) => tokio::time::sleep(wait).await,
                    None => std::future::pending().await,
                }
            };
            tokio::select! {
                biased;
                () = shutdown.recv() => break,
                () = paced => self.send_paced().await,
                out = outgoing.recv() => {
                    let Some(out) = out else { break };
                    let mut batch = vec![out];
                    while batch.len() < MAX_BATCH {
                        match outgoing.try_recv() {
                            Ok(out) => batch.push(out),
                            Err(_) => break,
                        }
                    }
                    if self.governor.is_some() {
                        self.offer(batch);
                        self.send_paced().await;
                    } else {
                        self.send(&batch).await;
                    }
                }
                received = self.socket.recv_from(&mut buf) => {
                    let (len, peer) = match received {
                        Ok(r) => r,
                        // An ICMP "port unreachable" for an earlier send (reported on some platforms):
                        // about one peer, not the link.
                        Err(e) if matches!(e.kind(), ErrorKind::ConnectionRefused | ErrorKind::ConnectionReset) => {
                            tracing::debug!(error = %e, "UDP peer unreachable");
                            self.counters.add_send_error();
                            continue;
                        }
                        Err(source) => return Err(LinkError::Receive { local: self.local, source }),
                    };
                    let frames = decoder.decode_datagram(&buf[..len]);
                    if frames.is_empty() {
                        tracing::debug!(%peer, len, "UDP datagram without a valid frame dropped");
                        continue;
                    }
                    if self.peers.heard(peer, Instant::now()) {
                        tracing::info!(%peer, "UDP ground-station peer joined");
                    }
                    let frames = self.signing.verify(frames, &self.counters);
                    if let Some(g) = &mut self.governor {
                        g.take_radio_status(&frames);
                    }
                    if !deliver(&incoming, &self.counters, self.link, peer, frames) {
                        return Ok(());
                    }
                }
            }
        }
        tracing::info!(local = %self.local, "UDP ground-station link stopped");
        Ok(())
    }

    /// Hands `batch` to the governor, each message counted once per destination.
    fn offer(&mut self, batch: Vec<Outgoing>) {
        let Some(g) = &mut self.governor else { return };
        for peer in self.peers.expire(Instant::now()) {
            tracing::info!(%peer, "UDP ground-station peer expired");
        }
        let broadcast_to = self.peers.broadcast_targets().len().max(1);
        let signed = self.signing.enabled();
        for out in batch {
            let copies = if matches!(out.to, Destination::Peer(_)) { 1 } else { broadcast_to };
            g.offer(out, signed, copies);
        }
    }

    /// Sends what the governor allows now, numbered by the link.
    async fn send_paced(&mut self) {
        let Some(g) = &mut self.governor else { return };
        let ready = g.ready(&format!("udp://{}", self.local));
        self.send(&ready).await;
    }

    /// Sends `batch` in order, one frame per datagram: to every broadcast target, or a reply to its peer.
    /// (Packing several frames into one datagram, as PX4 does, saves system calls, but pymavlink parses
    /// one frame per datagram it reads and falls ever further behind a vehicle that runs faster than real
    /// time.)
    async fn send(&mut self, batch: &[Outgoing]) {
        for out in batch {
            let bytes = self.signing.encode(out.header, &out.message);
            match out.to {
                Destination::All => self.broadcast(&bytes).await,
                Destination::Peer(peer) => self.send_to(&bytes, peer).await,
            }
        }
    }

    /// One datagram to every fixed target and live peer.
    async fn broadcast(&mut self, datagram: &[u8]) {
        for peer in self.peers.expire(Instant::now()) {
            tracing::info!(%peer, "UDP ground-station peer expired");
        }
        for target in self.peers.broadcast_targets() {
            self.send_to(datagram, target).await;
        }
    }

    async fn send_to(&self, datagram: &[u8], target: SocketAddr) {
        match self.socket.send_to(datagram, target).await {
            Ok(_) => self.counters.add_sent(datagram.len()),
            Err(e) => {
                self.counters.add_send_error();
                tracing::debug!(%target, error = %e, "UDP send failed");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::mavlink::link_rate::MAX_FRAME_BYTES;
    use crate::runtime::frame::DecodedFrame;
    use crate::runtime::frame::FrameDecoder;
    use crate::runtime::frame::encode_v2;
    use crate::runtime::frame::tests::{heartbeat, signed};
    use crate::runtime::link::CHANNEL_CAPACITY;
    use crate::runtime::shutdown::{self, ShutdownTrigger};
    use mavlink::MavHeader;
    use mavlink::dialects::common::{COMMAND_ACK_DATA, MavCmd, MavMessage, MavResult};
    use tokio::task::JoinHandle;

    const VEHICLE: MavHeader = MavHeader { system_id: 1, component_id: 1, sequence: 0 };
    /// Long enough for a loopback datagram; with paused time it costs nothing.
    const WAIT: Duration = Duration::from_millis(500);

    struct Harness {
        link_addr: SocketAddr,
        fixed: UdpSocket,
        incoming: mpsc::Receiver<Incoming>,
        outgoing: mpsc::Sender<Outgoing>,
        counters: Arc<LinkCounters>,
        trigger: ShutdownTrigger,
        task: JoinHandle<Result<(), LinkError>>,
    }

    async fn loopback_socket() -> UdpSocket {
        UdpSocket::bind("127.0.0.1:0").await.expect("bind loopback")
    }

    async fn start() -> Harness {
        let fixed = loopback_socket().await;
        let config = UdpConfig {
            link: 0,
            bind: "127.0.0.1:0".parse().expect("addr"),
            targets: vec![fixed.local_addr().expect("addr")],
            ..UdpConfig::default()
        };
        let link = UdpLink::bind(config).await.expect("bind link");
        let link_addr = link.local_addr();
        let counters = link.counters();
        let (in_tx, incoming) = mpsc::channel(CHANNEL_CAPACITY);
        let (outgoing, out_rx) = mpsc::channel(CHANNEL_CAPACITY);
        let (trigger, shutdown) = shutdown::channel();
        let task = tokio::spawn(link.run(in_tx, out_rx, shutdown));
        Harness { link_addr, fixed, incoming, outgoing, counters, trigger, task }
    }

    async fn send_heartbeat(sock: &UdpSocket, to: SocketAddr, seq: u8) {
        let (h, m) = heartbeat(255, seq);
        sock.send_to(&encode_v2(h, &m), to).await.expect("send");
    }

    /// The frames of the next datagram, or None if none comes within [`WAIT`].
    async fn next_frames(sock: &UdpSocket) -> Option<Vec<DecodedFrame>> {
        let mut buf = vec![0u8; MAX_DATAGRAM_BYTES];
        let (len, _) = tokio::time::timeout(WAIT, sock.recv_from(&mut buf)).await.ok()?.expect("recv");
        Some(FrameDecoder::new().decode_datagram(&buf[..len]))
    }

    async fn expect_heartbeat(sock: &UdpSocket, seq: u8, who: &str) {
        let frames = next_frames(sock).await.unwrap_or_else(|| panic!("{who}: no heartbeat {seq}"));
        assert_eq!(frames.len(), 1, "{who}");
        assert!(matches!(frames[0].message, MavMessage::HEARTBEAT(_)), "{who}: {:?}", frames[0].message);
        assert_eq!(frames[0].header.sequence, seq, "{who}");
    }

    async fn broadcast_heartbeat(h: &Harness, seq: u8) {
        let (_, message) = heartbeat(1, seq);
        let header = MavHeader { sequence: seq, ..VEHICLE };
        h.outgoing.send(Outgoing { to: Destination::All, header, message }).await.expect("link alive");
    }

    async fn next_incoming(h: &mut Harness) -> Incoming {
        tokio::time::timeout(WAIT, h.incoming.recv()).await.expect("incoming in time").expect("link alive")
    }

    #[test]
    fn every_instance_sends_to_qgroundcontrols_port_and_its_own_api_port() {
        let c = UdpConfig::for_ports(&InstancePorts::of(2).expect("in range"));
        assert_eq!(c.bind, "0.0.0.0:18572".parse().expect("addr"));
        assert_eq!(c.targets, vec!["127.0.0.1:14550".parse().expect("addr"), "127.0.0.1:14542".parse().expect("addr")]);
        assert_eq!(c.peer_expiry, Duration::from_secs(10));
    }

    #[test]
    fn peer_table_expires_peers_not_fixed_targets_and_never_doubles() {
        let fixed: SocketAddr = "127.0.0.1:14550".parse().expect("addr");
        let peer: SocketAddr = "127.0.0.1:40000".parse().expect("addr");
        let mut t = PeerTable::new(vec![fixed], Duration::from_secs(10), MAX_UDP_PEERS);
        let t0 = Instant::now();
        assert!(t.heard(peer, t0));
        assert!(!t.heard(peer, t0 + Duration::from_secs(1)));
        assert!(t.heard(fixed, t0), "a fixed target that talks is also a peer");
        assert_eq!(t.broadcast_targets(), vec![fixed, peer]);
        assert!(t.expire(t0 + Duration::from_millis(10_999)).contains(&fixed));
        assert_eq!(t.broadcast_targets(), vec![fixed, peer]);
        assert_eq!(t.expire(t0 + Duration::from_secs(11)), vec![peer]);
        assert_eq!(t.broadcast_targets(), vec![fixed]);
    }

    #[tokio::test(start_paused = true)]
    async fn talking_and_silent_peers_both_receive_every_broadcast() {
        let mut h = start().await;
        let talker = loopback_socket().await;
        let script = loopback_socket().await;
        // The script peer sends one message and then only listens.
        send_heartbeat(&script, h.link_addr, 0).await;
        assert_eq!(next_incoming(&mut h).await.peer, script.local_addr().expect("addr"));
        send_heartbeat(&talker, h.link_addr, 0).await;
        assert_eq!(next_incoming(&mut h).await.peer, talker.local_addr().expect("addr"));
        for seq in 0..8u8 {
            broadcast_heartbeat(&h, seq).await;
            expect_heartbeat(&talker, seq, "talker").await;
            expect_heartbeat(&script, seq, "script").await;
            expect_heartbeat(&h.fixed, seq, "fixed").await;
            tokio::time::sleep(Duration::from_secs(1)).await;
            send_heartbeat(&talker, h.link_addr, seq + 1).await;
            assert_eq!(next_incoming(&mut h).await.header.sequence, seq + 1);
        }
        let s = h.counters.snapshot();
        assert_eq!((s.frames_in, s.frames_out, s.malformed), (10, 24, 0));
    }

    #[tokio::test(start_paused = true)]
    async fn a_silent_peer_expires_fixed_targets_do_not() {
        let mut h = start().await;
        let peer = loopback_socket().await;
        send_heartbeat(&peer, h.link_addr, 0).await;
        next_incoming(&mut h).await;
        tokio::time::sleep(Duration::from_millis(9_900)).await;
        broadcast_heartbeat(&h, 1).await;
        expect_heartbeat(&peer, 1, "peer before expiry").await;
        expect_heartbeat(&h.fixed, 1, "fixed").await;
        tokio::time::sleep(Duration::from_millis(200)).await;
        broadcast_heartbeat(&h, 2).await;
        expect_heartbeat(&h.fixed, 2, "fixed after the peer expired").await;
        assert!(next_frames(&peer).await.is_none(), "an expired peer receives nothing");
        // Talking again brings it back.
        send_heartbeat(&peer, h.link_addr, 1).await;
        next_incoming(&mut h).await;
        broadcast_heartbeat(&h, 3).await;
        expect_heartbeat(&peer, 3, "peer rejoined").await;
        expect_heartbeat(&h.fixed, 3, "fixed").await;
    }

    #[tokio::test(start_paused = true)]
    async fn a_reply_reaches_only_its_peer() {
        let mut h = start().await;
        let (a, b) = (loopback_socket().await, loopback_socket().await);
        send_heartbeat(&a, h.link_addr, 0).await;
        send_heartbeat(&b, h.link_addr, 0).await;
        let from = next_incoming(&mut h).await.peer;
        next_incoming(&mut h).await;
        assert_eq!(from, a.local_addr().expect("addr"));
        let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            result: MavResult::MAV_RESULT_ACCEPTED,
            ..Default::default()
        });
        h.outgoing
            .send(Outgoing { to: Destination::Peer(from), header: VEHICLE, message: ack.clone() })
            .await
            .expect("send");
        let got = next_frames(&a).await.expect("the addressed peer gets the reply");
        assert_eq!(got[0].message, ack);
        assert!(next_frames(&b).await.is_none(), "the other peer gets nothing");
        assert!(next_frames(&h.fixed).await.is_none(), "the fixed target gets nothing");
    }

    #[tokio::test(start_paused = true)]
    async fn garbage_and_truncated_datagrams_are_counted_and_the_next_frame_delivered() {
        let mut h = start().await;
        let (peer, noise) = (loopback_socket().await, loopback_socket().await);
        let (hb_header, hb) = heartbeat(255, 7);
        let good = encode_v2(hb_header, &hb);
        noise.send_to(&[0x00, 0x13, 0x37, 0x42, 0x99], h.link_addr).await.expect("send");
        peer.send_to(&good[..good.len() - 4], h.link_addr).await.expect("send");
        let mut bad_crc = good.clone();
        bad_crc[12] ^= 0x5A;
        peer.send_to(&bad_crc, h.link_addr).await.expect("send");
        // A signed v2 frame is read (signature skipped), then a plain one.
        peer.send_to(&signed(&good, 0), h.link_addr).await.expect("send");
        peer.send_to(&good, h.link_addr).await.expect("send");
        for _ in 0..2 {
            let got = next_incoming(&mut h).await;
            assert_eq!((got.peer, got.header, &got.message), (peer.local_addr().expect("addr"), hb_header, &hb));
        }
        let s = h.counters.snapshot();
        assert_eq!(s.frames_in, 2);
        assert_eq!(s.malformed, 2, "{s:?}");
        assert!(s.garbage_bytes >= 5, "the noise datagram and the dropped frames' bytes: {s:?}");
        // Noise does not make a peer.
        broadcast_heartbeat(&h, 0).await;
        expect_heartbeat(&peer, 0, "peer").await;
        assert!(next_frames(&noise).await.is_none(), "a sender of garbage is not a peer");
    }

    #[tokio::test(start_paused = true)]
    async fn shutdown_ends_the_link_and_closes_the_incoming_channel() {
        let mut h = start().await;
        h.trigger.fire();
        let res = tokio::time::timeout(WAIT, h.task).await.expect("ends promptly").expect("no panic");
        assert!(res.is_ok());
        assert!(h.incoming.recv().await.is_none(), "sender dropped on exit");
    }

    #[tokio::test(start_paused = true)]
    async fn the_core_closing_outgoing_ends_the_link() {
        let h = start().await;
        drop(h.outgoing);
        let res = tokio::time::timeout(WAIT, h.task).await.expect("ends promptly").expect("no panic");
        assert!(res.is_ok());
    }

    #[tokio::test]
    async fn binding_a_taken_port_is_a_typed_error() {
        let taken = UdpSocket::bind("127.0.0.1:0").await.expect("bind");
        let config = UdpConfig { bind: taken.local_addr().expect("addr"), ..UdpConfig::default() };
        let err = UdpLink::bind(config).await.expect_err("port taken");
        assert!(matches!(err, LinkError::Bind { .. }), "{err}");
    }

    #[test]
    fn a_flood_of_new_senders_cannot_grow_the_peer_table_past_its_cap() {
        let mut table = PeerTable::new(vec![], Duration::from_secs(10), MAX_UDP_PEERS);
        let now = Instant::now();
        for port in 0..(MAX_UDP_PEERS as u16 + 10) {
            table.heard(SocketAddr::from(([127, 0, 0, 1], 20_000 + port)), now);
        }
        assert_eq!(table.peers().count(), MAX_UDP_PEERS);
        assert_eq!(table.refused(), 10);
        // A live peer is still heard; once the others expire, a new one is taken again.
        assert!(!table.heard(SocketAddr::from(([127, 0, 0, 1], 20_000)), now));
        table.expire(now + Duration::from_secs(11));
        assert!(table.heard(SocketAddr::from(([127, 0, 0, 1], 30_000)), now + Duration::from_secs(11)));
    }

    #[tokio::test(start_paused = true)]
    async fn with_a_data_rate_the_output_is_paced_and_an_ack_overtakes_a_parameter_burst() {
        use mavlink::dialects::common::{MavParamType, PARAM_VALUE_DATA};
        let fixed = loopback_socket().await;
        let config = UdpConfig {
            bind: "127.0.0.1:0".parse().expect("addr"),
            targets: vec![fixed.local_addr().expect("addr")],
            data_rate: 2000,
            ..UdpConfig::default()
        };
        let link = UdpLink::bind(config).await.expect("bind link");
        let (in_tx, _incoming) = mpsc::channel(CHANNEL_CAPACITY);
        let (outgoing, out_rx) = mpsc::channel(CHANNEL_CAPACITY);
        let (trigger, shutdown) = shutdown::channel();
        let param = |index: u16| PARAM_VALUE_DATA {
            param_value: 1.5,
            param_count: 100,
            param_index: index,
            param_id: "MPC_XY_CRUISE".into(),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        };
        for index in 0..100 {
            let message = MavMessage::PARAM_VALUE(param(index));
            outgoing.send(Outgoing { to: Destination::All, header: VEHICLE, message }).await.expect("queued");
        }
        let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
            result: MavResult::MAV_RESULT_ACCEPTED,
            ..COMMAND_ACK_DATA::default()
        });
        outgoing.send(Outgoing { to: Destination::All, header: VEHICLE, message: ack }).await.expect("queued");
        let task = tokio::spawn(link.run(in_tx, out_rx, shutdown));
        let start = Instant::now();
        let mut got = Vec::new();
        let mut bytes = 0;
        while got.len() < 101 {
            let frames = next_frames(&fixed).await.expect("every frame comes");
            bytes += frames.iter().map(|f| encode_v2(f.header, &f.message).len()).sum::<usize>();
            got.extend(frames.into_iter().map(|f| (f.header.sequence, f.message)));
        }
        let elapsed = start.elapsed().as_secs_f64();
        assert!(matches!(got[0].1, MavMessage::COMMAND_ACK(_)), "the ACK goes first: {:?}", got[0].1);
        let sequences: Vec<u8> = got.iter().map(|(s, _)| *s).collect();
        assert_eq!(sequences, (0..101).collect::<Vec<u8>>(), "numbered by the link");
        // Paced at 2000 B/s after the bucket's one frame.
        let floor = (bytes - MAX_FRAME_BYTES) as f64 / 2000.0;
        assert!(elapsed >= floor - 0.01 && elapsed < floor + 0.2, "{bytes} B in {elapsed:.3} s");
        trigger.fire();
        task.await.expect("task").expect("clean stop");
    }
}
