//! The plan store: the one copy of what the vehicle was given to fly. The mission (as uploaded, and as
//! the navigator flies it: [`NavItem`]s derived once, shared with the executor, never copied), the
//! geofence, the rally points and the mission's current item. The MAVLink mission service transfers plans
//! in and out of it; the navigator reads the mission from it; the setpoint guard checks against its fence.

use std::sync::Arc;

use super::geofence::{Fence, Rally};
use crate::core::mission::{Mission, MissionError, NavItem, nav_items};

/// The plans. See the module docs.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Plan {
    mission: Mission,
    items: Arc<[NavItem]>,
    fence: Fence,
    rally: Rally,
    current_seq: u16,
}

impl Plan {
    /// The mission as uploaded.
    #[must_use]
    pub fn mission(&self) -> &Mission {
        &self.mission
    }

    /// The mission as the navigator flies it (shared, not copied).
    #[must_use]
    pub fn items(&self) -> Arc<[NavItem]> {
        Arc::clone(&self.items)
    }

    /// Stores a valid `mission`, current item 0.
    ///
    /// # Errors
    /// [`Mission::validate`]'s; the stored mission is then unchanged.
    pub fn set_mission(&mut self, mission: Mission) -> Result<(), MissionError> {
        mission.validate()?;
        self.items = nav_items(&mission).into();
        self.mission = mission;
        self.current_seq = 0;
        Ok(())
    }

    /// No mission.
    pub fn clear_mission(&mut self) {
        self.mission = Mission::default();
        self.items = Arc::from([]);
        self.current_seq = 0;
    }

    #[must_use]
    pub fn fence(&self) -> &Fence {
        &self.fence
    }

    pub fn set_fence(&mut self, fence: Fence) {
        self.fence = fence;
    }

    #[must_use]
    pub fn rally(&self) -> &Rally {
        &self.rally
    }

    pub fn set_rally(&mut self, rally: Rally) {
        self.rally = rally;
    }

    /// The item the mission flies towards (flagged `current` in downloads).
    #[must_use]
    pub fn current_seq(&self) -> u16 {
        self.current_seq
    }

    /// The navigator's current item, as it moves.
    pub fn set_current_seq(&mut self, seq: u16) {
        self.current_seq = seq;
    }
}
