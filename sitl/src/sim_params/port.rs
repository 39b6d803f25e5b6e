//! The SIM_ parameter port: the plant's [`SimParamService`] on its own UDP socket (127.0.0.1:19550 + N),
//! with the peers that spoke to it, the plant's truth stream to them and the plant's heartbeat. It owns
//! no service: the plant link that steps the plant holds the one service and lends it to every poll.

use std::io;
use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::time::{Duration, Instant};

use autopilot::core::plant_link::{FrameDecoder, encode_frame_v1, encode_frame_v2};
use mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType};
use mavlink::{MavHeader, MavlinkVersion};

use super::{PLANT_COMPONENT_ID, SimParamService, TruthStream};
use crate::plant::Plant;

/// A peer that has not spoken for this long gets no more heartbeats.
pub const PEER_EXPIRY: Duration = Duration::from_secs(10);
/// Wall time between two heartbeats to the peers.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);

/// The plant's HEARTBEAT (see the module documentation for the type).
#[must_use]
pub fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    })
}

/// A client that spoke to the plant.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Peer {
    addr: SocketAddr,
    heard: Instant,
    version: MavlinkVersion,
}

/// The SIM_ parameter service on its UDP socket (non-blocking): each [`SimParamLink::poll`] reads every
/// datagram waiting, answers it, sends the truth samples taken since the last poll and the heartbeat when
/// due.
#[derive(Debug)]
pub struct SimParamLink {
    socket: UdpSocket,
    system_id: u8,
    decoder: FrameDecoder,
    peers: Vec<Peer>,
    truth: TruthStream,
    next_heartbeat: Instant,
    sequence: u8,
    buf: Vec<u8>,
}

impl SimParamLink {
    /// Bind `addr` (e.g. `127.0.0.1:19550`, or port 0 in tests) for system `system_id`, the truth stream
    /// starting at `plant`'s time. The service it answers from is lent to each [`SimParamLink::poll`]; it
    /// must answer for the same system ([`SimParamService::set_system_id`]).
    ///
    /// # Errors
    /// The bind or socket-option error.
    pub fn bind(addr: impl ToSocketAddrs, system_id: u8, plant: &Plant) -> io::Result<Self> {
        let socket = UdpSocket::bind(addr)?;
        socket.set_nonblocking(true)?;
        Ok(Self {
            socket,
            system_id,
            decoder: FrameDecoder::new(),
            peers: Vec::new(),
            truth: TruthStream::new(plant.time_us()),
            next_heartbeat: Instant::now(),
            sequence: 0,
            buf: vec![0; 65_536],
        })
    }

    /// The bound address.
    ///
    /// # Errors
    /// The socket's error.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// The system it speaks for (the header of everything it sends).
    #[must_use]
    pub fn system_id(&self) -> u8 {
        self.system_id
    }

    /// After every plant step: take the truth sample due at the plant's time, if anyone listens (no
    /// system call; it goes out at the next poll).
    pub fn stepped(&mut self, plant: &Plant) {
        self.truth.stepped(plant, !self.peers.is_empty());
    }

    fn send(&mut self, msg: &MavMessage, to: SocketAddr, version: MavlinkVersion) -> io::Result<()> {
        self.send_all(std::slice::from_ref(msg), to, version)
    }

    /// `msgs` in one datagram, in order.
    fn send_all(&mut self, msgs: &[MavMessage], to: SocketAddr, version: MavlinkVersion) -> io::Result<()> {
        let mut bytes = Vec::with_capacity(128 * msgs.len());
        for msg in msgs {
            let header = MavHeader {
                system_id: self.system_id.into(),
                component_id: PLANT_COMPONENT_ID,
                sequence: self.sequence,
            };
            self.sequence = self.sequence.wrapping_add(1);
            bytes.extend(match version {
                MavlinkVersion::V1 => encode_frame_v1(header, msg).unwrap_or_else(|| encode_frame_v2(header, msg)),
                MavlinkVersion::V2 => encode_frame_v2(header, msg),
            });
        }
        match self.socket.send_to(&bytes, to) {
            Ok(_) => Ok(()),
            Err(e) if autopilot::runtime::transport::is_transient(&e) => Ok(()),
            Err(e) => Err(e),
        }
    }

    /// Read and answer everything waiting through `service`, send what `service` holds for the peers (what
    /// forwarded failure injections and a scenario's events changed) and the truth samples taken since the
    /// last poll to the peers (one datagram each), then the heartbeat to the live peers if it is due.
    ///
    /// # Errors
    /// A socket error that is not transient (a client gone away is transient).
    pub fn poll(&mut self, service: &mut SimParamService, plant: &mut Plant) -> io::Result<()> {
        loop {
            let (n, from) = match self.socket.recv_from(&mut self.buf) {
                Ok(got) => got,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(e) if autopilot::runtime::transport::is_transient(&e) => continue,
                Err(e) => return Err(e),
            };
            let frames = self.decoder.decode_datagram(&self.buf[..n]);
            let now = Instant::now();
            for frame in frames {
                match self.peers.iter_mut().find(|p| p.addr == from) {
                    Some(p) => {
                        p.heard = now;
                        p.version = frame.version;
                    }
                    None => self.peers.push(Peer { addr: from, heard: now, version: frame.version }),
                }
                let replies = service.on_message(&frame.message, plant);
                for reply in replies {
                    self.send(&reply, from, frame.version)?;
                }
            }
        }
        // The injections' texts and values, and what a scenario's events set, to every peer.
        let outbox = service.take_outbox();
        for p in self.peers.clone() {
            if !outbox.is_empty() {
                self.send_all(&outbox, p.addr, p.version)?;
            }
        }
        let samples = self.truth.take();
        for p in self.peers.clone() {
            for sample in &samples {
                self.send_all(sample, p.addr, p.version)?;
            }
        }
        let now = Instant::now();
        if now >= self.next_heartbeat {
            self.next_heartbeat = now + HEARTBEAT_PERIOD;
            self.peers.retain(|p| now.saturating_duration_since(p.heard) < PEER_EXPIRY);
            let beat = heartbeat();
            for p in self.peers.clone() {
                self.send(&beat, p.addr, p.version)?;
            }
        }
        Ok(())
    }
}
