//! Every zenoh key expression Sinew uses, built in one place.
//!
//! Layout: `sinew/<scene>/...`. Scene, device, object and participant ids are single key segments: non-empty,
//! and free of `/ * $ # ?` and whitespace, which [`validate_segment`] enforces before any key is built.

use thiserror::Error;

/// An id that cannot be a key segment.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("`{id}` cannot be used as a {what} id: {reason}")]
pub struct KeyError {
    /// What the id names (scene, device, object, participant).
    pub what: &'static str,
    /// The offending id.
    pub id: String,
    /// Why.
    pub reason: &'static str,
}

/// Check that `id` is usable as one key segment.
pub fn validate_segment(what: &'static str, id: &str) -> Result<(), KeyError> {
    let fail = |reason| {
        Err(KeyError {
            what,
            id: id.to_owned(),
            reason,
        })
    };
    if id.is_empty() {
        return fail("empty");
    }
    if id.len() > 64 {
        return fail("longer than 64 bytes");
    }
    if id
        .chars()
        .any(|c| matches!(c, '/' | '*' | '$' | '#' | '?') || c.is_whitespace() || c.is_control())
    {
        return fail("contains one of / * $ # ? or whitespace");
    }
    Ok(())
}

/// Key expressions of one scene.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SceneKeys {
    prefix: String,
}

impl SceneKeys {
    /// Keys for `scene`.
    pub fn new(scene: &str) -> Result<Self, KeyError> {
        validate_segment("scene", scene)?;
        Ok(Self {
            prefix: format!("sinew/{scene}"),
        })
    }

    /// `sinew/<scene>/device/<id>/pose`: [`crate::DevicePose`].
    pub fn device_pose(&self, device_id: &str) -> Result<String, KeyError> {
        validate_segment("device", device_id)?;
        Ok(format!("{}/device/{device_id}/pose", self.prefix))
    }

    /// Every device's pose key.
    pub fn all_device_poses(&self) -> String {
        format!("{}/device/*/pose", self.prefix)
    }

    /// The device id in a pose (or force) key, if `key` is one of this scene's device keys.
    pub fn device_id_of<'k>(&self, key: &'k str) -> Option<&'k str> {
        let rest = key
            .strip_prefix(self.prefix.as_str())?
            .strip_prefix("/device/")?;
        let (id, tail) = rest.split_once('/')?;
        (tail == "pose" || tail == "force").then_some(id)
    }

    /// `sinew/<scene>/device/<id>/force`: [`crate::ForceCommand`].
    pub fn device_force(&self, device_id: &str) -> Result<String, KeyError> {
        validate_segment("device", device_id)?;
        Ok(format!("{}/device/{device_id}/force", self.prefix))
    }

    /// `sinew/<scene>/mesh/<object>/delta`: [`crate::MeshDelta`].
    pub fn mesh_delta(&self, object: &str) -> Result<String, KeyError> {
        validate_segment("object", object)?;
        Ok(format!("{}/mesh/{object}/delta", self.prefix))
    }

    /// Every object's delta key.
    pub fn all_mesh_deltas(&self) -> String {
        format!("{}/mesh/*/delta", self.prefix)
    }

    /// `sinew/<scene>/snapshot`: queryable answering [`crate::SceneSnapshot`].
    pub fn snapshot(&self) -> String {
        format!("{}/snapshot", self.prefix)
    }

    /// `sinew/<scene>/tools`: [`crate::ToolStates`].
    pub fn tools(&self) -> String {
        format!("{}/tools", self.prefix)
    }

    /// `sinew/<scene>/stats`: [`crate::ServerStats`].
    pub fn stats(&self) -> String {
        format!("{}/stats", self.prefix)
    }

    /// `sinew/<scene>/presence/<role>/<id>`: a zenoh liveliness token.
    pub fn presence(&self, role: crate::Role, id: &str) -> Result<String, KeyError> {
        validate_segment("participant", id)?;
        Ok(format!(
            "{}/presence/{}/{id}",
            self.prefix,
            role.key_segment()
        ))
    }

    /// Every key of the scene (`sinew/<scene>/**`): what a recorder taps.
    pub fn everything(&self) -> String {
        format!("{}/**", self.prefix)
    }

    /// Every presence token, of any role.
    pub fn every_presence(&self) -> String {
        format!("{}/presence/**", self.prefix)
    }

    /// Every presence token of one role.
    pub fn all_presence(&self, role: crate::Role) -> String {
        format!("{}/presence/{}/*", self.prefix, role.key_segment())
    }

    /// The participant id in a presence key of `role`.
    pub fn presence_id_of<'k>(&self, role: crate::Role, key: &'k str) -> Option<&'k str> {
        key.strip_prefix(self.prefix.as_str())?
            .strip_prefix("/presence/")?
            .strip_prefix(role.key_segment())?
            .strip_prefix('/')
            .filter(|id| !id.contains('/'))
    }

    /// `sinew/<scene>/hello/<role>/<id>`: [`crate::ParticipantHello`].
    pub fn hello(&self, role: crate::Role, id: &str) -> Result<String, KeyError> {
        validate_segment("participant", id)?;
        Ok(format!("{}/hello/{}/{id}", self.prefix, role.key_segment()))
    }

    /// Every hello of one role.
    pub fn all_hello(&self, role: crate::Role) -> String {
        format!("{}/hello/{}/*", self.prefix, role.key_segment())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Role;

    #[test]
    fn keys_round_trip_ids() {
        let keys = SceneKeys::new("pad").unwrap();
        let pose = keys.device_pose("left").unwrap();
        assert_eq!(pose, "sinew/pad/device/left/pose");
        assert_eq!(keys.device_id_of(&pose), Some("left"));
        assert_eq!(keys.device_id_of("sinew/pad/device/left/other"), None);
        assert_eq!(keys.device_id_of("sinew/other/device/left/pose"), None);
        let presence = keys.presence(Role::Haptic, "right").unwrap();
        assert_eq!(keys.presence_id_of(Role::Haptic, &presence), Some("right"));
        assert_eq!(keys.presence_id_of(Role::Viewer, &presence), None);
    }

    #[test]
    fn bad_segments_are_refused() {
        for bad in ["", "a/b", "a*", "$x", "a b", "q?"] {
            assert!(SceneKeys::new(bad).is_err(), "{bad:?} accepted");
        }
        let keys = SceneKeys::new("pad").unwrap();
        assert!(keys.device_pose("**").is_err());
    }
}
