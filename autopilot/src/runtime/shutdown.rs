//! The shutdown signal, mini-redis style: one [`ShutdownTrigger`] fires, every task holds a [`Shutdown`]
//! and `select!`s on [`Shutdown::recv`]; tasks then drain by dropping their channel senders.

use tokio::sync::watch;

/// Fires the shutdown for every [`Shutdown`] made from it. Dropping it also fires it, so a shell that
/// returns early never leaves tasks running.
#[derive(Debug)]
pub struct ShutdownTrigger {
    tx: watch::Sender<bool>,
}

/// A task's view of the shutdown signal. Cheap to clone.
#[derive(Debug, Clone)]
pub struct Shutdown {
    rx: watch::Receiver<bool>,
}

/// A trigger and its first listener.
#[must_use]
pub fn channel() -> (ShutdownTrigger, Shutdown) {
    let (tx, rx) = watch::channel(false);
    (ShutdownTrigger { tx }, Shutdown { rx })
}

impl ShutdownTrigger {
    /// Tell every listener to stop.
    pub fn fire(&self) {
        self.tx.send_replace(true);
    }

    /// Another listener.
    #[must_use]
    pub fn subscribe(&self) -> Shutdown {
        Shutdown { rx: self.tx.subscribe() }
    }
}

impl Drop for ShutdownTrigger {
    fn drop(&mut self) {
        self.fire();
    }
}

impl Shutdown {
    /// Whether shutdown has been fired.
    #[must_use]
    pub fn is_shutdown(&self) -> bool {
        *self.rx.borrow()
    }

    /// Resolves once shutdown is fired (at once if it already was, or if the trigger is gone).
    pub async fn recv(&mut self) {
        // An Err means the trigger was dropped, which also means stop.
        let _ = self.rx.wait_for(|&stop| stop).await;
    }
}

/// Resolves on SIGTERM (how service managers and `kill` stop a process), never elsewhere than on Unix.
pub async fn terminated() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{SignalKind, signal};
        if let Ok(mut term) = signal(SignalKind::terminate()) {
            term.recv().await;
            return;
        }
    }
    std::future::pending::<()>().await;
}

/// Resolves when standard input reaches its end (a detached thread reads it, so a pending read never
/// holds up the process exit).
pub async fn stdin_closed() {
    let (tx, rx) = tokio::sync::oneshot::channel();
    std::thread::spawn(move || {
        let mut sink = [0u8; 256];
        let mut stdin = std::io::stdin();
        while std::io::Read::read(&mut stdin, &mut sink).is_ok_and(|n| n > 0) {}
        let _ = tx.send(());
    });
    let _ = rx.await;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn fire_and_drop_both_release_listeners() {
        let (trigger, mut a) = channel();
        let mut b = trigger.subscribe();
        assert!(!a.is_shutdown());
        trigger.fire();
        a.recv().await;
        assert!(a.is_shutdown());
        let (trigger2, mut c) = channel();
        drop(trigger2);
        c.recv().await;
        b.recv().await;
    }
}
