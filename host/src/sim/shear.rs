//! Scripted pushes that shear a pack ([`Layout::Packed`](super::Layout::Packed) and
//! [`Layout::Mixed`](super::Layout::Mixed) scenes): part of the objects slides along a
//! face it shares with the rest, and the rest stays, so the push separates look-alike
//! neighbours instead of carrying the whole pack.
//!
//! A candidate is an object and a horizontal direction:
//! - a box (sharp or rounded) is pushed along one of its four face normals;
//! - any other shape across the line joining its centre to a touching neighbour's, as in a
//!   loose scene.
//!
//! It qualifies if the pusher can reach the trailing face (the start of
//! [`SimScene::push_start`] is clear of every object: a free, outer face) and the push
//! shears: the objects it would carry (the pushed one, and transitively every object a
//! carried one would run into, by more than 1 mm, if it moved rigidly along the push; tested
//! at every quarter of the push) are not all of them, and one of them touches an object that is left
//! behind. In a grid that is an outer box pushed out sideways, or an outer row or column
//! pushed along its length past the next one.

use parry3d::math::Vector as GlamVec;
use rapier3d::prelude::Collider;

use crate::rig::robot::PushCommand;

use super::{
    CM_PER_M, ObjectShape, ScriptedPush, SimScene, TOUCH_GAP_M, across, dir_from_sim,
    point_from_sim,
};

/// A carried object penetrates the next by more than this before it counts as pushing it,
/// centimetres (1 mm): sliding along a neighbour turned by a degree does not.
const CARRY_DEPTH_CM: f32 = 0.1;
/// Points along the push where carrying is tested, as fractions of its length.
const CARRY_SAMPLES: [f32; 4] = [0.25, 0.5, 0.75, 1.0];

impl SimScene {
    /// Every qualifying shear push of `length_m` (module docs), in label order.
    pub(super) fn shear_pushes(&self, length_m: f32) -> Vec<ScriptedPush> {
        let touching = self.touching_pairs(TOUCH_GAP_M);
        let mut candidates = Vec::new();
        for o in &self.objects {
            let label = o.info.label;
            let Some(c) = self.world.colliders.get(o.collider) else {
                continue;
            };
            for dir in self.push_directions(label, o.info.shape, c, &touching) {
                let Some(start) = self.push_start(c, dir) else {
                    continue;
                };
                let carried = self.carried(label, dir * (length_m * CM_PER_M));
                let shears = carried.len() < self.objects.len()
                    && touching
                        .iter()
                        .any(|(a, b)| carried.contains(a) != carried.contains(b));
                if shears {
                    candidates.push(ScriptedPush {
                        command: PushCommand {
                            start_robot_m: point_from_sim(start),
                            direction_robot: dir_from_sim(dir),
                            length_m,
                        },
                        target: label,
                    });
                }
            }
        }
        candidates
    }

    /// The horizontal unit directions `label` may be pushed in (module docs).
    fn push_directions(
        &self,
        label: u16,
        shape: ObjectShape,
        collider: &Collider,
        touching: &[(u16, u16)],
    ) -> Vec<GlamVec> {
        match shape {
            ObjectShape::Box { .. } | ObjectShape::RoundedBox { .. } => {
                let rotation = collider.position().rotation;
                [GlamVec::X, GlamVec::Y]
                    .into_iter()
                    .filter_map(|axis| {
                        let a = rotation * axis;
                        GlamVec::new(a.x, a.y, 0.0).try_normalize()
                    })
                    .flat_map(|d| [d, -d])
                    .collect()
            }
            _ => touching
                .iter()
                .filter_map(|&(a, b)| match label {
                    l if l == a => Some(b),
                    l if l == b => Some(a),
                    _ => None,
                })
                .filter_map(|other| across(collider, self.collider_of(other)?))
                .flat_map(|d| [d, -d])
                .collect(),
        }
    }

    /// Labels of the objects a push of `label` by `delta_cm` would carry (module docs),
    /// `label` first.
    fn carried(&self, label: u16, delta_cm: GlamVec) -> Vec<u16> {
        let mut carried = vec![label];
        let mut next = 0;
        while let Some(&mover) = carried.get(next) {
            next += 1;
            let Some(m) = self.collider_of(mover) else {
                continue;
            };
            for o in &self.objects {
                if carried.contains(&o.info.label) {
                    continue;
                }
                let Some(c) = self.world.colliders.get(o.collider) else {
                    continue;
                };
                let hit = CARRY_SAMPLES.iter().any(|f| {
                    let mut moved = *m.position();
                    moved.translation += delta_cm * *f;
                    parry3d::query::contact(&moved, m.shape(), c.position(), c.shape(), 0.0)
                        .is_ok_and(|k| k.is_some_and(|k| k.dist < -CARRY_DEPTH_CM))
                });
                if hit {
                    carried.push(o.info.label);
                }
            }
        }
        carried
    }
}

#[cfg(test)]
mod tests {
    use super::super::{DEFAULT_PUSH_LEN_M, Layout, ObjectPose, SimConfig, dir_to_sim};
    use super::*;

    #[test]
    fn shear_pushes_move_part_of_a_pack_and_leave_the_rest() {
        let config = SimConfig::D415.with_layout(Layout::Packed);
        for seed in 0..8 {
            let mut sim = SimScene::with_config(seed, config).unwrap();
            let before = sim.object_poses();
            let push = sim
                .scripted_push(DEFAULT_PUSH_LEN_M)
                .unwrap_or_else(|| panic!("seed {seed}: no shear push"));
            assert!(
                push.command.direction_robot.z.abs() < 1e-6,
                "pushes are horizontal"
            );
            let mut predicted = sim.carried(
                push.target,
                dir_to_sim(&push.command.direction_robot) * (push.command.length_m * CM_PER_M),
            );
            predicted.sort_unstable();
            sim.push(&push.command).unwrap();
            let after = sim.object_poses();
            let along = |b: &ObjectPose, a: &ObjectPose| {
                (a.world_from_object.translation.vector - b.world_from_object.translation.vector)
                    .dot(&push.command.direction_robot)
            };
            let moved_m: Vec<(u16, f32)> = before
                .iter()
                .zip(&after)
                .map(|(b, a)| (b.label, along(b, a)))
                .collect();
            println!("seed {seed}: pushed {} {moved_m:?}", push.target);
            let carried: Vec<u16> = moved_m
                .iter()
                .filter(|(_, m)| *m > 0.01)
                .map(|(l, _)| *l)
                .collect();
            let stayed = moved_m.iter().filter(|(_, m)| m.abs() < 0.002).count();
            assert!(carried.contains(&push.target), "seed {seed}: target moved");
            assert!(stayed > 0, "seed {seed}: part of the pack stays");
            assert!(
                carried.len() + stayed == moved_m.len(),
                "seed {seed}: every object either moves with the push or stays"
            );
            assert_eq!(carried, predicted, "seed {seed}: the carried objects");
        }
    }
}
