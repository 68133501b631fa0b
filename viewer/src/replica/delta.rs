//! The rules that decide what a mesh delta does to a [`SceneReplica`]: apply it, ignore it as stale, or
//! refuse it as a gap or a protocol error, and the outcomes and errors that say which.
//!
//! Owns: [`SceneReplica::apply_delta`], [`DeltaOutcome`] and [`ReplicaError`]. Every check runs before any
//! write, so a refused delta changes nothing.
//!
//! Must not: touch zenoh, threads, clocks or rendering, or panic whatever the delta holds. Whether a topology
//! change fits an object is the object's to say (`object`).

use sinew_protocol::MeshDelta;
use thiserror::Error;

use super::SceneReplica;

/// What [`SceneReplica::apply_delta`] did with a delta it accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeltaOutcome {
    /// The delta followed the object's frame; its positions are now in the replica.
    Applied,
    /// The delta's frame is already folded into the object (e.g. it predates the snapshot); ignored.
    Stale,
}

/// Why a delta was refused. Every variant means "re-query the snapshot"; none changes the replica.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum ReplicaError {
    /// The delta does not follow the object's frame: something was missed.
    #[error(
        "gap on object {object}: replica at frame {have_frame}, delta {frame} follows frame {prev_frame}"
    )]
    Gap {
        /// Object index.
        object: u16,
        /// The replica object's frame.
        have_frame: u64,
        /// The frame the delta follows.
        prev_frame: u64,
        /// The delta's frame.
        frame: u64,
    },
    /// The delta names an object the replica does not have (or no snapshot was applied yet).
    #[error("delta for object {object}, but the replica has {objects} objects")]
    UnknownObject {
        /// Object index in the delta.
        object: u16,
        /// Objects in the replica.
        objects: usize,
    },
    /// A vertex index past the end of the object's vertices (a protocol error).
    #[error(
        "delta for object {object} names vertex {index}, but the object has {vertex_count} vertices"
    )]
    IndexOutOfRange {
        /// Object index.
        object: u16,
        /// Offending vertex index.
        index: u32,
        /// Vertices in the replica object.
        vertex_count: usize,
    },
    /// A topology change that does not follow the object's topology epoch: one was missed.
    #[error(
        "topology gap on object {object}: replica at epoch {have_epoch}, change to epoch {epoch}"
    )]
    TopologyGap {
        /// Object index.
        object: u16,
        /// The replica object's epoch.
        have_epoch: u32,
        /// The change's epoch.
        epoch: u32,
    },
    /// A topology change that does not fit the object (a protocol error).
    #[error("topology change for object {object}: {reason}")]
    BadTopology {
        /// Object index.
        object: u16,
        /// What does not fit.
        reason: String,
    },
    /// Indices and positions differ in length (a protocol error; decoding refuses this too).
    #[error("delta for object {object} has {indices} indices but {positions} positions")]
    LengthMismatch {
        /// Object index.
        object: u16,
        /// Number of indices.
        indices: usize,
        /// Number of positions.
        positions: usize,
    },
}

impl ReplicaError {
    /// True for a protocol error (the delta itself is wrong), false for a gap (something was missed).
    pub fn is_protocol_error(&self) -> bool {
        !matches!(
            self,
            ReplicaError::Gap { .. } | ReplicaError::TopologyGap { .. }
        )
    }
}
impl SceneReplica {
    /// Fold one delta into its object.
    ///
    /// Applies iff `delta.prev_frame` equals the object's frame; a delta whose frame is not after the object's
    /// is [`DeltaOutcome::Stale`]; anything else is a [`ReplicaError::Gap`]. Indices are checked before any
    /// position is written, so a refused delta changes nothing. Never panics, whatever the delta holds.
    pub fn apply_delta(&mut self, delta: &MeshDelta) -> Result<DeltaOutcome, ReplicaError> {
        let objects = self.objects.len();
        let object =
            self.objects
                .get_mut(usize::from(delta.object))
                .ok_or(ReplicaError::UnknownObject {
                    object: delta.object,
                    objects,
                })?;
        if delta.frame <= object.frame {
            return Ok(DeltaOutcome::Stale);
        }
        if delta.prev_frame != object.frame {
            return Err(ReplicaError::Gap {
                object: delta.object,
                have_frame: object.frame,
                prev_frame: delta.prev_frame,
                frame: delta.frame,
            });
        }
        if delta.indices.len() != delta.positions_q.len() {
            return Err(ReplicaError::LengthMismatch {
                object: delta.object,
                indices: delta.indices.len(),
                positions: delta.positions_q.len(),
            });
        }
        if delta.burn_indices.len() != delta.burn.len() {
            return Err(ReplicaError::LengthMismatch {
                object: delta.object,
                indices: delta.burn_indices.len(),
                positions: delta.burn.len(),
            });
        }
        if let Some(change) = &delta.topology {
            object.check_topology(change)?;
        }
        let vertex_count =
            object.positions_q.len() + delta.topology.as_ref().map_or(0, |t| t.parents.len());
        if let Some(&index) = delta
            .indices
            .iter()
            .chain(&delta.burn_indices)
            .find(|&&i| !usize::try_from(i).is_ok_and(|i| i < vertex_count))
        {
            return Err(ReplicaError::IndexOutOfRange {
                object: delta.object,
                index,
                vertex_count,
            });
        }
        if let Some(change) = &delta.topology {
            object.apply_topology(change);
            self.topology_revision = self.revision + 1;
        }
        for (&index, &position_q) in delta.indices.iter().zip(&delta.positions_q) {
            // In range: checked above.
            if let Some(slot) = object.positions_q.get_mut(index as usize) {
                *slot = position_q;
            }
        }
        for (&index, &level) in delta.burn_indices.iter().zip(&delta.burn) {
            if let Some(slot) = object.burn.get_mut(index as usize) {
                *slot = level;
            }
        }
        object.frame = delta.frame;
        self.revision += 1;
        Ok(DeltaOutcome::Applied)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::replica::ReplicaObject;
    // The sheet's bounds, as these tests call them.
    use crate::test_fixtures::SHEET_BOUNDS as BOUNDS;
    use crate::test_fixtures::{
        PROBE_ABOVE_MM, diff_delta, quantize_all, sheet_positions_mm, sheet_snapshot,
    };

    #[test]
    fn snapshot_then_deltas_in_order_equals_the_expected_state() {
        let n = 5;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica =
            SceneReplica::from_snapshot(sheet_snapshot(start.clone(), n, 10, PROBE_ABOVE_MM));
        assert!(replica.has_snapshot());
        assert_eq!(replica.frame(), 10);

        let mut expected = start.clone();
        expected[12] = [100, 200, 300];
        let first = diff_delta(&start, &expected, 10, 11);
        assert_eq!(replica.apply_delta(&first), Ok(DeltaOutcome::Applied));

        let mut next = expected.clone();
        next[0] = [1, 2, 3];
        next[24] = [65535, 65535, 65535];
        let second = diff_delta(&expected, &next, 11, 13);
        assert_eq!(replica.apply_delta(&second), Ok(DeltaOutcome::Applied));

        assert_eq!(replica.quantized(0), next.as_slice());
        assert_eq!(replica.object(0).map(ReplicaObject::frame), Some(13));
        assert_eq!(replica.frame(), 13);
        let mm = replica.positions_mm(0).unwrap();
        assert_eq!(mm[24], BOUNDS.max_mm);
        assert_eq!(replica.max_error_mm(0), Some(BOUNDS.max_error_mm()));
        assert!(replica.max_error_mm(0).unwrap() < 0.002);
    }

    #[test]
    fn stale_delta_is_ignored() {
        let n = 4;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica =
            SceneReplica::from_snapshot(sheet_snapshot(start.clone(), n, 20, PROBE_ABOVE_MM));
        let before = replica.clone();
        let revision = replica.revision();
        let mut moved = start.clone();
        moved[3] = [9, 9, 9];
        // Already folded into the snapshot: frame <= the object's frame.
        for (prev, frame) in [(19, 20), (15, 18), (0, 1)] {
            let delta = diff_delta(&start, &moved, prev, frame);
            assert_eq!(replica.apply_delta(&delta), Ok(DeltaOutcome::Stale));
        }
        assert_eq!(replica, before);
        assert_eq!(replica.revision(), revision);
    }

    #[test]
    fn gap_is_detected_and_state_unchanged() {
        let n = 4;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica =
            SceneReplica::from_snapshot(sheet_snapshot(start.clone(), n, 20, PROBE_ABOVE_MM));
        let before = replica.clone();
        let mut moved = start.clone();
        moved[3] = [9, 9, 9];
        let delta = diff_delta(&start, &moved, 21, 22);
        assert_eq!(
            replica.apply_delta(&delta),
            Err(ReplicaError::Gap {
                object: 0,
                have_frame: 20,
                prev_frame: 21,
                frame: 22
            })
        );
        assert_eq!(replica, before);
    }

    #[test]
    fn burn_levels_apply_travel_in_the_snapshot_and_bad_ones_change_nothing() {
        let n = 4;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica = SceneReplica::from_snapshot(sheet_snapshot(start, n, 20, PROBE_ABOVE_MM));
        assert!(replica.objects()[0].burn().iter().all(|&b| b == 0));
        let burnt = MeshDelta {
            object: 0,
            frame: 21,
            prev_frame: 20,
            burn_indices: vec![3, 7],
            burn: vec![40, 255],
            ..MeshDelta::default()
        };
        assert_eq!(replica.apply_delta(&burnt), Ok(DeltaOutcome::Applied));
        assert_eq!(replica.objects()[0].burn()[3], 40);
        assert_eq!(replica.objects()[0].burn()[7], 255);
        // A late joiner's snapshot carries them.
        let again = SceneReplica::from_snapshot(replica.to_snapshot());
        assert_eq!(again.objects()[0].burn(), replica.objects()[0].burn());
        // A burn index past the vertices, or a count that does not match, changes nothing.
        let before = replica.clone();
        for bad in [
            MeshDelta {
                frame: 22,
                prev_frame: 21,
                indices: vec![1],
                positions_q: vec![[9, 9, 9]],
                burn_indices: vec![2, 16],
                burn: vec![1, 2],
                ..MeshDelta::default()
            },
            MeshDelta {
                frame: 22,
                prev_frame: 21,
                burn_indices: vec![2],
                burn: vec![1, 2],
                ..MeshDelta::default()
            },
        ] {
            let err = replica.apply_delta(&bad).unwrap_err();
            assert!(err.is_protocol_error(), "{err}");
            assert_eq!(replica, before);
        }
    }

    #[test]
    fn out_of_range_index_is_refused_with_state_unchanged() {
        let n = 4;
        let start = quantize_all(&sheet_positions_mm(n));
        let mut replica = SceneReplica::from_snapshot(sheet_snapshot(start, n, 20, PROBE_ABOVE_MM));
        let before = replica.clone();
        // Index 2 is valid and comes first: it must not be written either.
        let delta = MeshDelta {
            object: 0,
            frame: 21,
            prev_frame: 20,
            indices: vec![2, 16],
            positions_q: vec![[1, 1, 1], [2, 2, 2]],
            ..MeshDelta::default()
        };
        let err = replica.apply_delta(&delta).unwrap_err();
        assert_eq!(
            err,
            ReplicaError::IndexOutOfRange {
                object: 0,
                index: 16,
                vertex_count: 16
            }
        );
        assert!(err.is_protocol_error());
        assert_eq!(replica, before);

        let huge = MeshDelta {
            indices: vec![u32::MAX],
            positions_q: vec![[0, 0, 0]],
            ..delta.clone()
        };
        assert!(replica.apply_delta(&huge).is_err());
        let mismatched = MeshDelta {
            indices: vec![1, 2],
            positions_q: vec![[0, 0, 0]],
            ..delta
        };
        assert!(matches!(
            replica.apply_delta(&mismatched),
            Err(ReplicaError::LengthMismatch { .. })
        ));
        assert_eq!(replica, before);
    }

    #[test]
    fn delta_before_any_snapshot_is_unknown_object() {
        let mut replica = SceneReplica::new();
        let delta = MeshDelta {
            object: 0,
            frame: 2,
            prev_frame: 1,
            ..MeshDelta::default()
        };
        assert_eq!(
            replica.apply_delta(&delta),
            Err(ReplicaError::UnknownObject {
                object: 0,
                objects: 0
            })
        );
        assert!(!replica.has_snapshot());
        assert_eq!(replica.max_error_mm_all(), 0.0);
    }

    /// Random walk of a mesh on a "server" side, quantized and diffed into deltas like the server does; one
    /// delta is dropped: the replica must report a gap, keep its state, and equal the server after a resnapshot.
    #[test]
    fn random_walk_with_a_dropped_delta_is_detected_and_resnapshot_converges() {
        let mut rng = fastrand::Rng::with_seed(0x5eed);
        let n = 12;
        let mut server_mm = sheet_positions_mm(n);
        let mut server_q = quantize_all(&server_mm);
        let mut server_frame = 100u64;
        let mut last_delta_frame = server_frame;
        let mut replica = SceneReplica::from_snapshot(sheet_snapshot(
            server_q.clone(),
            n,
            server_frame,
            PROBE_ABOVE_MM,
        ));
        let drop_at = 37;
        let mut gap_seen = false;

        for step in 0..80 {
            server_frame += 1;
            // Move a few vertices (sometimes none) by up to 0.2 mm per axis.
            for _ in 0..rng.usize(0..10) {
                let v = rng.usize(0..server_mm.len());
                for coordinate in &mut server_mm[v] {
                    *coordinate += (rng.f32() - 0.5) * 0.4;
                }
            }
            let now_q = quantize_all(&server_mm);
            let delta = diff_delta(&server_q, &now_q, last_delta_frame, server_frame);
            server_q = now_q;
            if delta.indices.is_empty() {
                continue; // The server sends nothing while the object is still.
            }
            last_delta_frame = server_frame;
            if step == drop_at {
                continue; // Lost on the way.
            }
            let before = replica.clone();
            match replica.apply_delta(&delta) {
                Ok(DeltaOutcome::Applied) => assert!(!gap_seen, "applied after a gap"),
                Ok(DeltaOutcome::Stale) => panic!("no delta here is stale"),
                Err(ReplicaError::Gap { .. }) => {
                    gap_seen = true;
                    assert_eq!(replica, before, "a gap changed the replica");
                }
                Err(other) => panic!("unexpected {other}"),
            }
            if !gap_seen {
                assert_eq!(replica.quantized(0), server_q.as_slice());
            }
        }
        assert!(gap_seen, "the dropped delta was not detected");
        assert_ne!(replica.quantized(0), server_q.as_slice());

        let mut resnapshot = sheet_snapshot(server_q.clone(), n, server_frame, PROBE_ABOVE_MM);
        resnapshot.objects[0].frame = last_delta_frame;
        replica.apply_snapshot(resnapshot);
        assert_eq!(replica.quantized(0), server_q.as_slice());
        for (replica_mm, truth_mm) in replica
            .object(0)
            .unwrap()
            .positions_mm_iter()
            .zip(&server_mm)
        {
            let err: f32 = (0..3)
                .map(|a| (replica_mm[a] - truth_mm[a]).powi(2))
                .sum::<f32>()
                .sqrt();
            assert!(
                err <= BOUNDS.max_error_mm() * 1.001 + 1e-5,
                "error {err} mm"
            );
        }
    }
}
