//! The serial ground-station link: a telemetry radio or a USB cable to a ground station, one peer, MAVLink
//! 2 out (v1 accepted in). In: the port's byte stream through one stream decoder; each valid frame goes to
//! the core as an [`Incoming`] (peer `0.0.0.0:0`: a serial link has one peer), a RADIO_STATUS (from the
//! radio: any system id, typically SiK's 51/68) also to the link's governor. Out: every [`Outgoing`],
//! whatever its destination, through the link's [`LinkGovernor`] (`core::mavlink::link_rate`), which fits
//! the output to the link's data rate as PX4 does: HEARTBEAT, COMMAND_ACK and STATUSTEXT first and never
//! thinned, parameter and mission transfers and replies next, in order, then the telemetry streams, thinned
//! by PX4's rate multiplier (the data rate against the offered bytes, and the radio's RADIO_STATUS
//! `txbuf`) and only the newest of each waiting. The data rate is [`SerialConfig::data_rate`]: baud / 10
//! bytes/s (8N1) unless `[gcs] serial_data_rate` says otherwise (bytes/s; 0: unlimited, where only a
//! radio's RADIO_STATUS thins the streams).
//!
//! The port is blocking (the `serialport` crate), so the link runs on a blocking thread: it reads for up
//! to [`POLL_INTERVAL`], or until the pacer next has a frame to write if that is sooner, hands what it
//! decoded to the core, takes everything the core queued into the governor, then writes what the pacer
//! allows. The UART's buffer so holds at most about a frame beyond what the line is sending, so a
//! HEARTBEAT or a COMMAND_ACK never waits behind a parameter burst. Frames are numbered by the link
//! (MAVLink's sequence per link, as PX4's), so a ground station counts the streams' thinning as what it
//! is, not as loss. A write that fails is counted and the link keeps going (a radio out of range); a read
//! error that is not a timeout stops the link as a [`LinkError`]. A change of the multiplier by 10 % or more
//! is logged at debug, by more than a factor 2 since the last such at info.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TryRecvError;

use super::frame::{CountingDecoder, LinkCounters};
use super::link::{GovernedOutput, Incoming, LinkError, LinkId, Outgoing, deliver};
use super::shutdown::Shutdown;
use super::signing::LinkSigning;
use super::transport::{SerialTransport, Transport};

/// How long a read waits at most before the queued output is taken: the output latency of the link.
pub const POLL_INTERVAL: Duration = Duration::from_millis(10);
/// How long a write may wait for room in the port's buffer before it counts as failed.
pub const WRITE_TIMEOUT: Duration = Duration::from_millis(100);

/// The serial port to serve.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SerialConfig {
    /// This link's id (its index in the runtime's link list).
    pub link: LinkId,
    /// Device path (`/dev/ttyUSB0`).
    pub path: String,
    pub baud: u32,
    /// Bytes/s the link's output is fitted to ([`bytes_per_s_of_baud`](crate::core::plant_link::budget::bytes_per_s_of_baud) by default, `[gcs] serial_data_rate`);
    /// 0: unlimited.
    pub data_rate: u64,
}

/// An open serial link, ready to [`SerialLink::run`].
#[derive(Debug)]
pub struct SerialLink {
    link: LinkId,
    port: SerialTransport,
    counters: Arc<LinkCounters>,
    signing: Arc<LinkSigning>,
    output: GovernedOutput,
}

/// The peer address a serial link reports its frames with.
const SERIAL_PEER: SocketAddr = SocketAddr::V4(std::net::SocketAddrV4::new(std::net::Ipv4Addr::UNSPECIFIED, 0));

impl SerialLink {
    /// Open the port.
    ///
    /// # Errors
    /// [`LinkError::Open`] if the device cannot be opened at that baud rate.
    pub fn open(config: &SerialConfig) -> Result<Self, LinkError> {
        let port = SerialTransport::open(&config.path, config.baud, POLL_INTERVAL)
            .map_err(|source| LinkError::Open { what: format!("serial {}", config.path), source })?;
        tracing::info!(
            path = %config.path,
            baud = config.baud,
            data_rate = config.data_rate,
            "serial ground-station link open (data rate in bytes/s, 0: unlimited)"
        );
        Ok(Self {
            link: config.link,
            port,
            counters: LinkCounters::new_shared(),
            signing: Arc::default(),
            output: GovernedOutput::new(config.data_rate),
        })
    }

    /// Signs and verifies with the process's shared signing state (default: its own, off).
    #[must_use]
    pub fn with_signing(mut self, signing: Arc<LinkSigning>) -> Self {
        self.signing = signing;
        self
    }

    /// The link's counters.
    #[must_use]
    pub fn counters(&self) -> Arc<LinkCounters> {
        self.counters.clone()
    }

    /// Move frames until shutdown fires, the core drops its receiver of `incoming`, or the core closes
    /// `outgoing`.
    ///
    /// # Errors
    /// [`LinkError::Io`] when reading the port fails (the device went away).
    pub async fn run(
        self,
        incoming: mpsc::Sender<Incoming>,
        outgoing: mpsc::Receiver<Outgoing>,
        shutdown: Shutdown,
    ) -> Result<(), LinkError> {
        tokio::task::spawn_blocking(move || self.serve(&incoming, outgoing, &shutdown))
            .await
            .map_err(|e| LinkError::Io(std::io::Error::other(e)))?
    }

    fn serve(
        mut self,
        incoming: &mpsc::Sender<Incoming>,
        mut outgoing: mpsc::Receiver<Outgoing>,
        shutdown: &Shutdown,
    ) -> Result<(), LinkError> {
        let mut decoder = CountingDecoder::new(self.counters.clone());
        let path = self.port.describe();
        while !shutdown.is_shutdown() {
            let wait = self.output.next_ready_in().map_or(POLL_INTERVAL, |wait| wait.min(POLL_INTERVAL));
            self.port.set_timeout(wait)?;
            if let Some(bytes) = self.port.recv()? {
                let frames = self.signing.verify(decoder.push(bytes), &self.counters);
                self.output.take_radio_status(&frames);
                if !deliver(incoming, &self.counters, self.link, SERIAL_PEER, frames) {
                    break;
                }
            }
            loop {
                match outgoing.try_recv() {
                    Ok(out) => self.output.offer(out, self.signing.enabled(), 1),
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => {
                        tracing::info!(%path, "serial ground-station link stopped");
                        return Ok(());
                    }
                }
            }
            self.port.set_timeout(WRITE_TIMEOUT)?;
            for out in self.output.ready(&path) {
                let bytes = self.signing.encode(out.header, &out.message);
                match self.port.write_unflushed(&bytes) {
                    Ok(()) => self.counters.add_sent(bytes.len()),
                    Err(e) => {
                        self.counters.add_send_error();
                        tracing::debug!(%path, error = %e, "serial write failed");
                    }
                }
            }
        }
        tracing::info!(%path, "serial ground-station link stopped");
        Ok(())
    }
}
