//! Tick ownership: who the ticker is, since when, and who ended the
//! ownership of a ticker that another client revoked by leaving
//! synchronous mode.

use iceoryx2::identifiers::UniqueClientId;
use shared_types::{FixedText, TickerInfo};

/// The current ticker.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Owner {
    /// Its port on the tick service.
    pub client: UniqueClientId,
    /// Its process (for a ticker on another host: the bridge's, whose
    /// death ends the ownership).
    pub pid: u32,
    /// The process reported as the ticker: `pid`, or for a ticker on
    /// another host, its pid there (its bridge's word).
    pub reported_pid: u32,
    /// Its iceoryx2 node name.
    pub node_name: String,
    /// The last frame published before it claimed ownership.
    pub since_frame: u64,
}

/// Who, if anyone, holds tick ownership.
#[derive(Debug, Default)]
pub(crate) struct TickOwnership {
    owner: Option<Owner>,
    /// A ticker whose ownership another client ended by leaving
    /// synchronous mode, and who did it: its next request is told so.
    revoked: Option<(UniqueClientId, TickerInfo)>,
}

impl TickOwnership {
    /// The owner, if any.
    pub(crate) fn owner(&self) -> Option<&Owner> {
        self.owner.as_ref()
    }

    /// Whether `client` is the owner.
    pub(crate) fn is_owner(&self, client: UniqueClientId) -> bool {
        self.owner.as_ref().is_some_and(|o| o.client == client)
    }

    /// Makes `candidate` the owner, unless another live owner holds it: then
    /// the current owner is returned as the error. A dead owner is replaced.
    pub(crate) fn claim(
        &mut self,
        candidate: Owner,
        owner_alive: impl Fn(u32) -> bool,
    ) -> Result<Owner, Owner> {
        if let Some(current) = &self.owner {
            if current.client != candidate.client && owner_alive(current.pid) {
                return Err(current.clone());
            }
        }
        self.revoked = None;
        match &self.owner {
            Some(current) if current.client == candidate.client => Ok(current.clone()),
            _ => Ok(self.owner.insert(candidate).clone()),
        }
    }

    /// Makes `candidate` (a standby taking over) the owner of a world
    /// nobody holds; `None` if someone does. Unlike [`Self::claim`], a
    /// revoked ticker is still told who revoked it.
    pub(crate) fn grant(&mut self, candidate: Owner) -> Option<Owner> {
        if self.owner.is_some() {
            return None;
        }
        Some(self.owner.insert(candidate).clone())
    }

    /// Ends the ownership of `client`; `false` if it was not the owner. A
    /// revoked ticker's release is accepted (and forgets the revocation).
    pub(crate) fn release(&mut self, client: UniqueClientId) -> bool {
        if self.revoked_by(client).is_some() {
            self.revoked = None;
            return true;
        }
        if self.is_owner(client) {
            self.owner = None;
            true
        } else {
            false
        }
    }

    /// Ends the current ownership because `by` left synchronous mode;
    /// returns the owner it ended.
    pub(crate) fn revoke(&mut self, by: TickerInfo) -> Option<Owner> {
        let owner = self.owner.take()?;
        self.revoked = Some((owner.client, by));
        Some(owner)
    }

    /// Who ended `client`'s ownership, if it was revoked.
    pub(crate) fn revoked_by(&self, client: UniqueClientId) -> Option<TickerInfo> {
        self.revoked
            .as_ref()
            .filter(|(revoked, _)| *revoked == client)
            .map(|(_, by)| *by)
    }

    /// Removes and returns the owner if `owner_alive` says its process died.
    pub(crate) fn take_if_dead(&mut self, owner_alive: impl Fn(u32) -> bool) -> Option<Owner> {
        if self.owner.as_ref().is_some_and(|o| !owner_alive(o.pid)) {
            self.owner.take()
        } else {
            None
        }
    }

    /// The owner as it travels on the wire.
    pub(crate) fn info(&self) -> TickerInfo {
        match &self.owner {
            Some(o) => TickerInfo {
                active: 1,
                pid: o.reported_pid,
                since_frame: o.since_frame,
                node_name: FixedText::new(&o.node_name),
            },
            None => TickerInfo::none(),
        }
    }
}
