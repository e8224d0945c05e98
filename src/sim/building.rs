//! What every indoor layout is made of: the classes, the configuration
//! and the kinds of world, rooms and the layout that records them, and
//! walls with openings. The layouts ([`super::corridor`],
//! [`super::open_plan`], [`super::offices`]) build on it; [`super::indoor`]
//! generates a world of any kind and is where the rest of omcl finds
//! these types. All sizes are metres, world z up, floor at z = 0.

use super::world::{Aabb, Scene, Shape, VoxelWorld};

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

impl IndoorLayout {
    /// Rooms whose doors open onto one straight way at world y = `y`: a
    /// hall node on it before every door, joined in the order of the doors'
    /// x, and the tour walking it end to end (the corridor apartment and
    /// the open-plan home's aisle).
    pub(super) fn along_line(
        kind: WorldKind,
        mut rooms: Vec<Room>,
        y: f64,
        wall_height: f64,
    ) -> Self {
        let mut hall = Vec::with_capacity(rooms.len());
        for rm in rooms.iter_mut() {
            rm.hall_node = hall.len();
            hall.push([rm.door[0], y]);
        }
        let mut tour: Vec<usize> = (0..rooms.len()).collect();
        tour.sort_by(|&a, &b| rooms[a].door[0].total_cmp(&rooms[b].door[0]));
        let hall_edges = tour
            .windows(2)
            .map(|e| [rooms[e[0]].hall_node, rooms[e[1]].hall_node])
            .collect();
        IndoorLayout {
            kind,
            rooms,
            hall,
            hall_edges,
            tour,
            wall_height,
        }
    }
}

/// A generated indoor world: primitives, layout and voxels.
#[derive(Debug, Clone)]
pub struct IndoorWorld {
    pub config: IndoorConfig,
    pub scene: Scene,
    pub layout: IndoorLayout,
    pub voxels: VoxelWorld,
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
