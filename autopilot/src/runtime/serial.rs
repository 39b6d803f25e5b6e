//! The serial ground-station link: a telemetry radio or a USB cable to a ground station, one peer, MAVLink
//! 2 out (v1 accepted in). In: the port's byte stream through one stream decoder; each valid frame goes to
//! the core as an [`Incoming`] (peer `0.0.0.0:0`: a serial link has one peer). Out: every [`Outgoing`],
//! whatever its destination, is written to the port.
//!
//! The port is blocking (the `serialport` crate), so the link runs on a blocking thread: it reads for up
//! to [`POLL_INTERVAL`], hands what it decoded to the core, then writes everything queued. A write that
//! fails is counted and the link keeps going (a radio out of range); a read error that is not a timeout
//! stops the link as a [`LinkError`].

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::sync::mpsc;
use tokio::sync::mpsc::error::TryRecvError;

use super::frame::{CountingDecoder, LinkCounters};
use super::link::{Incoming, LinkError, LinkId, Outgoing, deliver};
use super::shutdown::Shutdown;
use super::signing::LinkSigning;
use super::transport::{SerialTransport, Transport};

/// How long a read waits before the queued output is written: the output latency of the link.
pub const POLL_INTERVAL: Duration = Duration::from_millis(10);

/// The serial port to serve.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SerialConfig {
    /// This link's id (its index in the runtime's link list).
    pub link: LinkId,
    /// Device path (`/dev/ttyUSB0`).
    pub path: String,
    pub baud: u32,
}

/// An open serial link, ready to [`SerialLink::run`].
#[derive(Debug)]
pub struct SerialLink {
    link: LinkId,
    port: SerialTransport,
    counters: Arc<LinkCounters>,
    signing: Arc<LinkSigning>,
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
        tracing::info!(path = %config.path, baud = config.baud, "serial ground-station link open");
        Ok(Self { link: config.link, port, counters: LinkCounters::new_shared(), signing: Arc::default() })
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
            if let Some(bytes) = self.port.recv()? {
                let frames = self.signing.verify(decoder.push(bytes), &self.counters);
                if !deliver(incoming, &self.counters, self.link, SERIAL_PEER, frames) {
                    break;
                }
            }
            loop {
                match outgoing.try_recv() {
                    Ok(out) => {
                        let bytes = self.signing.encode(out.header, &out.message);
                        match self.port.send(&bytes) {
                            Ok(()) => self.counters.add_sent(bytes.len()),
                            Err(e) => {
                                self.counters.add_send_error();
                                tracing::debug!(%path, error = %e, "serial write failed");
                            }
                        }
                    }
                    Err(TryRecvError::Empty) => break,
                    Err(TryRecvError::Disconnected) => {
                        tracing::info!(%path, "serial ground-station link stopped");
                        return Ok(());
                    }
                }
            }
        }
        tracing::info!(%path, "serial ground-station link stopped");
        Ok(())
    }
}
