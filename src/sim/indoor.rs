//! Indoor worlds: their classes, layouts and the kinds there are.
//!
//! Three kinds of world ([`WorldKind`]): the corridor apartment
//! ([`super::corridor`], rooms off both sides of one corridor, the
//! benchmark's default), the open-plan home ([`super::open_plan`], one
//! large living, dining and kitchen space with long sight lines and two
//! side rooms) and the office floor ([`super::offices`], 20 or more rooms
//! round two corridors, most of them identical offices). Every layout
//! records its rooms (floor rectangle, door, a viewpoint kept free) and a
//! hall graph of the shared space that camera paths walk
//! ([`super::paths`]). Furniture is placed by room kind
//! ([`super::furniture`]), never in the strip from a door to its room's
//! viewpoint, so paths through doors and viewpoints are collision-free.
//! All sizes are metres, world z up, floor at z = 0.

use nalgebra::Vector3;

use super::world::{Aabb, Scene, Shape, VoxelWorld, voxelize};

/// Class names of indoor worlds; id = index. The first entries equal the
/// start of [`super::embeddings::SIM_CLASSES`].
pub const INDOOR_CLASSES: &[&str] = &[
    "wall",
    "floor",
    "ceiling",
    "door",
    "window",
    "table",
    "chair",
    "sofa",
    "bed",
    "cabinet",
    "shelving",
    "toilet",
    "sink",
    "mirror",
    "towel",
    "tv monitor",
    "picture",
    "plant",
    "rug",
    "lamp",
    "counter",
    "stove",
    "fridge",
    "bathtub",
    "cushion",
    "desk",
    "wardrobe",
    "nightstand",
    "curtain",
];

pub(super) const WALL: u16 = 0;
pub(super) const FLOOR: u16 = 1;
pub(super) const CEILING: u16 = 2;
pub(super) const DOOR: u16 = 3;
pub(super) const WINDOW: u16 = 4;
pub(super) const TABLE: u16 = 5;
pub(super) const CHAIR: u16 = 6;
pub(super) const SOFA: u16 = 7;
pub(super) const BED: u16 = 8;
pub(super) const CABINET: u16 = 9;
pub(super) const SHELVING: u16 = 10;
pub(super) const TOILET: u16 = 11;
pub(super) const SINK: u16 = 12;
pub(super) const MIRROR: u16 = 13;
pub(super) const TOWEL: u16 = 14;
pub(super) const TV: u16 = 15;
pub(super) const PICTURE: u16 = 16;
pub(super) const PLANT: u16 = 17;
pub(super) const RUG: u16 = 18;
pub(super) const LAMP: u16 = 19;
pub(super) const COUNTER: u16 = 20;
pub(super) const STOVE: u16 = 21;
pub(super) const FRIDGE: u16 = 22;
pub(super) const BATHTUB: u16 = 23;
pub(super) const CUSHION: u16 = 24;
pub(super) const DESK: u16 = 25;
pub(super) const WARDROBE: u16 = 26;
pub(super) const NIGHTSTAND: u16 = 27;
pub(super) const CURTAIN: u16 = 28;

/// Parameters of an indoor world.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IndoorConfig {
    /// Seed of every random draw of the layout.
    pub seed: u64,
    /// Voxel edge, metres (2 to 5 cm is the intended range).
    pub resolution: f64,
    /// Number of rooms (at least 1) of the corridor apartment; the office
    /// floor has at least [`super::offices::MIN_ROOMS`] (rounded up to a
    /// multiple of four); the open-plan home always has three zones and
    /// two side rooms.
    pub rooms: usize,
    /// Floor-to-ceiling height, metres.
    pub wall_height: f64,
    /// The kind of world (absent in older files: the corridor apartment).
    #[serde(default)]
    pub kind: WorldKind,
}

impl Default for IndoorConfig {
    fn default() -> Self {
        IndoorConfig {
            seed: 0,
            resolution: 0.05,
            rooms: 5,
            wall_height: 2.6,
            kind: WorldKind::Corridor,
        }
    }
}

impl IndoorConfig {
    /// The default world of `kind` with `seed` (24 rooms for the office
    /// floor, 5 otherwise).
    pub fn of_kind(kind: WorldKind, seed: u64) -> Self {
        IndoorConfig {
            seed,
            kind,
            rooms: if kind == WorldKind::Offices { 24 } else { 5 },
            ..Default::default()
        }
    }
}

/// The kinds of indoor world.
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "kebab-case")]
pub enum WorldKind {
    /// Rooms off both sides of one corridor (the benchmark's default).
    #[default]
    Corridor,
    /// One large living, dining and kitchen space and two side rooms.
    OpenPlan,
    /// 20 or more rooms round two corridors, most of them identical offices.
    Offices,
}

impl WorldKind {
    /// Every kind, the default first.
    pub const ALL: [WorldKind; 3] = [WorldKind::Corridor, WorldKind::OpenPlan, WorldKind::Offices];

    /// The name on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            WorldKind::Corridor => "corridor",
            WorldKind::OpenPlan => "open-plan",
            WorldKind::Offices => "offices",
        }
    }

    /// Whether this is the default kind (which sweeps leave out of their
    /// keys, so that corridor runs keep the ids they always had).
    pub fn is_corridor(&self) -> bool {
        *self == WorldKind::Corridor
    }
}

impl std::fmt::Display for WorldKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for WorldKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        WorldKind::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(s))
            .ok_or_else(|| {
                format!(
                    "unknown world {s:?}: one of {}",
                    WorldKind::ALL.map(|k| k.name()).join(", ")
                )
            })
    }
}

/// The purpose of a room, which decides its furniture.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum RoomKind {
    Living,
    Kitchen,
    Bathroom,
    Bedroom,
    Office,
    /// The dining part of an open plan.
    Dining,
}

/// One room: its floor rectangle, door and free viewpoint (world x, y).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Room {
    pub kind: RoomKind,
    /// Inner floor rectangle corners, metres.
    pub min: [f64; 2],
    pub max: [f64; 2],
    /// Centre of the door opening, on the corridor wall.
    pub door: [f64; 2],
    /// Unit vector from the door into the room.
    pub inward: [f64; 2],
    /// A point kept free of furniture, straight in from the door; camera
    /// paths turn in place here.
    pub viewpoint: [f64; 2],
    /// The hall node in front of the door (index into
    /// [`IndoorLayout::hall`]); the straight way from door to node is free.
    #[serde(default)]
    pub hall_node: usize,
    /// Rooms with the same `twin` hold the same contents in the same place
    /// up to a rigid motion (the office floor's templates); `None` for a
    /// room of its own.
    #[serde(default)]
    pub twin: Option<usize>,
}

/// Rooms of an indoor world and the hall that joins them.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IndoorLayout {
    pub kind: WorldKind,
    pub rooms: Vec<Room>,
    /// Waypoints of the shared space (corridors, aisles), world (x, y).
    pub hall: Vec<[f64; 2]>,
    /// Pairs of hall nodes joined by a free straight way.
    pub hall_edges: Vec<[usize; 2]>,
    /// Room indices in the order a walk visits them (it may start anywhere
    /// and wraps around).
    pub tour: Vec<usize>,
    pub wall_height: f64,
}

/// A generated indoor world: primitives, layout and voxels.
#[derive(Debug, Clone)]
pub struct IndoorWorld {
    pub config: IndoorConfig,
    pub scene: Scene,
    pub layout: IndoorLayout,
    pub voxels: VoxelWorld,
}

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

/// A gap in a wall: horizontal centre and width along the wall, and its
/// vertical extent; doors reach the floor, windows have a sill.
pub(super) struct Opening {
    centre: f64,
    width: f64,
    z0: f64,
    z1: f64,
    pane: bool,
}

impl Opening {
    pub(super) fn door(centre: f64) -> Self {
        Opening {
            centre,
            width: 0.9,
            z0: 0.0,
            z1: 2.1,
            pane: false,
        }
    }
    pub(super) fn window(centre: f64, width: f64) -> Self {
        Opening {
            centre,
            width,
            z0: 0.9,
            z1: 2.1,
            pane: true,
        }
    }
}

/// A wall along x at `y` from `xa` to `xb` with openings.
pub(super) fn wall_x(
    scene: &mut Scene,
    y: f64,
    xa: f64,
    xb: f64,
    t: f64,
    h: f64,
    openings: &[Opening],
) {
    wall(scene, xa, xb, t, h, openings, &|a0, a1, z0, z1, th| {
        Aabb::new([a0, y - th / 2.0, z0], [a1, y + th / 2.0, z1])
    });
}

/// A wall along y at `x` from `ya` to `yb` with openings.
pub(super) fn wall_y(
    scene: &mut Scene,
    x: f64,
    ya: f64,
    yb: f64,
    t: f64,
    h: f64,
    openings: &[Opening],
) {
    wall(scene, ya, yb, t, h, openings, &|a0, a1, z0, z1, th| {
        Aabb::new([x - th / 2.0, a0, z0], [x + th / 2.0, a1, z1])
    });
}

fn wall(
    scene: &mut Scene,
    a: f64,
    b: f64,
    t: f64,
    h: f64,
    openings: &[Opening],
    mk: &dyn Fn(f64, f64, f64, f64, f64) -> Aabb,
) {
    let mut ops: Vec<&Opening> = openings.iter().collect();
    ops.sort_by(|p, q| p.centre.total_cmp(&q.centre));
    let mut cur = a - t / 2.0;
    for op in ops {
        let o0 = op.centre - op.width / 2.0;
        let o1 = op.centre + op.width / 2.0;
        if o0 > cur {
            scene.add(WALL, Shape::Box(mk(cur, o0, 0.0, h, t)));
        }
        if op.z0 > 0.0 {
            scene.add(WALL, Shape::Box(mk(o0, o1, 0.0, op.z0, t)));
        }
        scene.add(WALL, Shape::Box(mk(o0, o1, op.z1, h, t)));
        if op.pane {
            scene.add(WINDOW, Shape::Box(mk(o0, o1, op.z0, op.z1, 0.02)));
        }
        cur = o1;
    }
    if b + t / 2.0 > cur {
        scene.add(WALL, Shape::Box(mk(cur, b + t / 2.0, 0.0, h, t)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
