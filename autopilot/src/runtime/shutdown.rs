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
