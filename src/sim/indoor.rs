//! Indoor worlds: their classes, layouts and the kinds there are.
//!
//! Three kinds of world ([`WorldKind`]): the corridor apartment
//! (`corridor`, rooms off both sides of one corridor, the
//! benchmark's default), the open-plan home (`open_plan`, one
//! large living, dining and kitchen space with long sight lines and two
//! side rooms) and the office floor ([`super::offices`], 20 or more rooms
//! round two corridors, most of them identical offices). Every layout
//! records its rooms (floor rectangle, door, a viewpoint kept free) and a
//! hall graph of the shared space that camera paths walk
//! ([`super::paths`]). Furniture is placed by room kind
//! (`furniture`), never in the strip from a door to its room's
//! viewpoint, so paths through doors and viewpoints are collision-free.
//! All sizes are metres, world z up, floor at z = 0.

use nalgebra::Vector3;

pub use super::building::{
    INDOOR_CLASSES, IndoorConfig, IndoorLayout, IndoorWorld, Room, RoomKind, WorldKind,
};
use super::world::{Aabb, voxelize};

/// Generates the world of `config` (deterministic in `config.seed`).
pub fn generate(config: &IndoorConfig) -> IndoorWorld {
    let (scene, layout) = match config.kind {
        WorldKind::Corridor => super::corridor::build(config),
        WorldKind::OpenPlan => super::open_plan::build(config),
        WorldKind::Offices => super::offices::build(config),
    };
    // Grid origin on a whole number of cells below the scene so that
    // boundaries at multiples of the resolution fall on cell faces.
    let r = config.resolution;
    let b = scene.bounds().unwrap_or(Aabb::new([0.0; 3], [0.0; 3]));
    let snap = |v: f64| ((v / r).floor() - 2.0) * r;
    let origin = Vector3::new(snap(b.min[0]), snap(b.min[1]), snap(b.min[2]));
    let voxels = voxelize(&scene, r, origin);
    IndoorWorld {
        config: config.clone(),
        scene,
        layout,
        voxels,
    }
}

#[cfg(test)]
mod tests {
    use super::super::building::*;
    use super::*;
    use crate::sim::world::VoxelWorld;

    fn count(w: &VoxelWorld, label: u16) -> usize {
        w.labels.iter().filter(|&&l| l == label).count()
    }

    #[test]
    fn default_world_has_rooms_furniture_and_all_classes() {
        let w = generate(&IndoorConfig::default());
        assert_eq!(w.layout.rooms.len(), 5);
        let hist = w.voxels.class_histogram();
        let present = hist.iter().filter(|&&n| n > 0).count();
        assert!(present >= 24, "only {present} classes: {hist:?}");
        for l in [
            WALL, FLOOR, CEILING, DOOR, WINDOW, TOILET, SINK, STOVE, BED, SOFA,
        ] {
            assert!(
                count(&w.voxels, l) > 0,
                "class {} missing",
                INDOOR_CLASSES[l as usize]
            );
        }
        // Floor covers the whole footprint at z in [-r, 0): floor cells lie in k = -1
        // relative to the z = 0 plane.
        let k_floor = ((0.0 - w.voxels.origin.z) / w.voxels.resolution).round() as i32 - 1;
        assert!(
            w.voxels
                .cells
                .iter()
                .zip(&w.voxels.labels)
                .filter(|(_, l)| **l == FLOOR)
                .all(|(c, _)| c[2] == k_floor)
        );
    }

    #[test]
    fn bathrooms_hold_toilets_and_kitchens_stoves() {
        let worlds = (0..4).map(|seed| (WorldKind::Corridor, seed)).chain([
            (WorldKind::OpenPlan, 0),
            (WorldKind::OpenPlan, 1),
            (WorldKind::Offices, 0),
        ]);
        for (kind, seed) in worlds {
            let w = generate(&IndoorConfig::of_kind(kind, seed));
            for rm in &w.layout.rooms {
                let inside = |label: u16| {
                    w.voxels.cells.iter().zip(&w.voxels.labels).any(|(c, &l)| {
                        let p = w.voxels.cell_centre(*c);
                        l == label
                            && p.x > rm.min[0]
                            && p.x < rm.max[0]
                            && p.y > rm.min[1]
                            && p.y < rm.max[1]
                    })
                };
                match rm.kind {
                    RoomKind::Bathroom => assert!(inside(TOILET) || inside(SINK), "{kind} {seed}"),
                    RoomKind::Kitchen => assert!(inside(STOVE) || inside(FRIDGE), "{kind} {seed}"),
                    _ => {}
                }
                assert!(!inside(TOILET) || rm.kind == RoomKind::Bathroom);
                assert!(!inside(STOVE) || rm.kind == RoomKind::Kitchen);
            }
        }
    }

    #[test]
    fn seeds_change_the_layout_and_repeat_exactly() {
        let a = generate(&IndoorConfig {
            seed: 1,
            ..Default::default()
        });
        let b = generate(&IndoorConfig {
            seed: 1,
            ..Default::default()
        });
        let c = generate(&IndoorConfig {
            seed: 2,
            ..Default::default()
        });
        assert_eq!(a.voxels, b.voxels);
        assert_ne!(a.voxels.cells, c.voxels.cells);
    }

    #[test]
    fn viewpoints_and_doors_are_free_of_furniture() {
        let worlds = (0..4).map(|seed| (WorldKind::Corridor, seed)).chain([
            (WorldKind::OpenPlan, 0),
            (WorldKind::OpenPlan, 1),
            (WorldKind::Offices, 0),
        ]);
        for (kind, seed) in worlds {
            let w = generate(&IndoorConfig::of_kind(kind, seed));
            for rm in &w.layout.rooms {
                for p in [rm.viewpoint, rm.door] {
                    // No occupied cell within 0.3 m horizontally between 0.2 m and 2 m high.
                    let hit = w.voxels.cells.iter().zip(&w.voxels.labels).any(|(c, &l)| {
                        let q = w.voxels.cell_centre(*c);
                        l != CEILING
                            && l != FLOOR
                            && l != RUG
                            && q.z > 0.2
                            && q.z < 2.0
                            && (q.x - p[0]).abs() < 0.3
                            && (q.y - p[1]).abs() < 0.3
                    });
                    assert!(!hit, "{kind} seed {seed} room {:?} point {p:?}", rm.kind);
                }
            }
        }
    }

    /// The labelled cells inside `rm` (walls, windows, floor and ceiling
    /// aside, 0.1 m in from its walls) in the room's own frame: cell
    /// offsets from the door wall's left corner looking in, sorted.
    fn contents(w: &IndoorWorld, rm: &Room) -> Vec<(u16, [i64; 3])> {
        let v = &w.voxels;
        let r = v.resolution;
        let mut out: Vec<(u16, [i64; 3])> = v
            .cells
            .iter()
            .zip(&v.labels)
            .filter(|(_, l)| !matches!(**l, WALL | WINDOW | FLOOR | CEILING))
            .filter_map(|(c, &l)| {
                let p = v.cell_centre(*c);
                let inside = p.x > rm.min[0] + 0.1
                    && p.x < rm.max[0] - 0.1
                    && p.y > rm.min[1] + 0.1
                    && p.y < rm.max[1] - 0.1;
                let (lx, ly) = if rm.inward[1] > 0.0 {
                    (p.x - rm.min[0], p.y - rm.min[1])
                } else {
                    (rm.max[0] - p.x, rm.max[1] - p.y)
                };
                inside.then(|| {
                    let q = [
                        (lx / r).floor() as i64,
                        (ly / r).floor() as i64,
                        c[2] as i64,
                    ];
                    (l, q)
                })
            })
            .collect();
        out.sort_unstable();
        out
    }

    #[test]
    fn office_floor_has_twenty_rooms_and_groups_of_identical_offices() {
        let w = generate(&IndoorConfig::of_kind(WorldKind::Offices, 5));
        let rooms = &w.layout.rooms;
        assert!(rooms.len() >= 20, "{} rooms", rooms.len());
        // Group the rooms by their contents, seen from their doors.
        let all: Vec<Vec<(u16, [i64; 3])>> = rooms.iter().map(|rm| contents(&w, rm)).collect();
        let mut groups: Vec<Vec<usize>> = Vec::new();
        for (i, c) in all.iter().enumerate() {
            assert!(c.len() > 500, "room {i} is nearly empty");
            match groups.iter_mut().find(|g| all[g[0]] == *c) {
                Some(g) => g.push(i),
                None => groups.push(vec![i]),
            }
        }
        let twins: Vec<&Vec<usize>> = groups.iter().filter(|g| g.len() >= 2).collect();
        assert!(twins.len() >= 2, "groups of identical rooms: {groups:?}");
        assert!(
            twins.iter().map(|g| g.len()).sum::<usize>() >= 12,
            "{groups:?}"
        );
        // Twins across a corridor (turned by half a turn) are among them.
        assert!(twins.iter().any(|g| {
            g.iter().any(|&i| rooms[i].inward[1] > 0.0)
                && g.iter().any(|&i| rooms[i].inward[1] < 0.0)
        }));
        // The layout's twin tags say the same.
        for g in &groups {
            let tag = rooms[g[0]].twin;
            assert!(g.iter().all(|&i| rooms[i].twin == tag), "{g:?}");
        }
        // Two different templates: their contents differ.
        assert_ne!(all[twins[0][0]], all[twins[1][0]]);
    }

    /// Mean free distance (m, at most 20) along 32 level rays at 1.5 m from
    /// every 5th pose of a path through `w`.
    fn mean_sight_line(w: &IndoorWorld) -> f64 {
        use crate::sim::paths::{IndoorPathConfig, indoor_path};
        let path = indoor_path(
            &w.layout,
            &IndoorPathConfig {
                frames: 400,
                ..Default::default()
            },
        );
        let v = &w.voxels;
        let step = 0.5 * v.resolution;
        let (mut sum, mut n) = (0.0, 0usize);
        for pose in path.iter().step_by(5) {
            let o = pose.translation.vector;
            for k in 0..32 {
                let a = k as f64 * std::f64::consts::TAU / 32.0;
                let dir = Vector3::new(a.cos(), a.sin(), 0.0);
                let mut s = 0.0;
                while s < 20.0 && v.label_at(v.cell_of(&(o + dir * s))).is_none() {
                    s += step;
                }
                sum += s;
                n += 1;
            }
        }
        sum / n as f64
    }

    #[test]
    fn open_plan_has_fewer_walls_and_longer_sight_lines_than_the_corridor() {
        let wall_share =
            |w: &IndoorWorld| count(&w.voxels, WALL) as f64 / count(&w.voxels, FLOOR) as f64;
        for seed in [0, 1] {
            let c = generate(&IndoorConfig::of_kind(WorldKind::Corridor, seed));
            let o = generate(&IndoorConfig::of_kind(WorldKind::OpenPlan, seed));
            let (wc, wo) = (wall_share(&c), wall_share(&o));
            assert!(
                wo < 0.75 * wc,
                "wall cells per floor cell: open {wo:.3}, corridor {wc:.3}"
            );
            let (sc, so) = (mean_sight_line(&c), mean_sight_line(&o));
            assert!(
                so > 1.4 * sc,
                "mean sight line: open {so:.2} m, corridor {sc:.2} m"
            );
        }
    }

    #[test]
    fn every_kind_repeats_per_seed_and_changes_with_it() {
        for kind in [WorldKind::OpenPlan, WorldKind::Offices] {
            let a = generate(&IndoorConfig::of_kind(kind, 7));
            let b = generate(&IndoorConfig::of_kind(kind, 7));
            let c = generate(&IndoorConfig::of_kind(kind, 8));
            assert_eq!(a.voxels, b.voxels, "{kind}");
            assert_eq!(a.layout, b.layout, "{kind}");
            assert_ne!(a.voxels.cells, c.voxels.cells, "{kind}");
            assert_eq!(a.layout.kind, kind);
        }
    }

    #[test]
    fn world_kinds_parse_from_their_names() {
        for k in WorldKind::ALL {
            assert_eq!(k.name().parse::<WorldKind>(), Ok(k));
        }
        assert!("hotel".parse::<WorldKind>().is_err());
        assert_eq!(IndoorConfig::default().kind, WorldKind::Corridor);
    }
}
