//! An office floor of 20 or more rooms: four rows of equal rooms along two
//! parallel corridors, joined at both ends into a loop. Most rooms are
//! offices furnished from one of two templates, so many rooms hold the same
//! furniture at the same place (turned by half a turn across a corridor);
//! a kitchenette, a lounge and two washrooms in the outer rows are the only
//! rooms of their kind. Global localization is ambiguous here by design:
//! an office seen from inside looks like every other office of its
//! template. Sizes are multiples of the voxel edge so that twin rooms are
//! twins voxel for voxel. Metres, world z up, floor at z = 0.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::building::{
    CEILING, FLOOR, IndoorConfig, IndoorLayout, Opening, PICTURE, Room, RoomKind, WorldKind,
    wall_x, wall_y,
};
use super::furniture::{self, door_leaf};
use super::world::{Aabb, Scene, Shape};

/// The fewest rooms an office floor has.
pub const MIN_ROOMS: usize = 20;

/// One of the four rows: its rooms' y range and which way their doors face.
struct Row {
    y_min: f64,
    y_max: f64,
    /// +1: the corridor is south of the row (doors on `y_min`, into +y).
    inward: f64,
    /// Outer rows have windows; inner rows are back to back.
    outer: bool,
    /// Corridor 0 (south) or 1 (north).
    corridor: usize,
}

/// A furnished office in its own frame: floor `[0, w] x [0, d]`, door on
/// y = 0 opening into +y, window on y = d.
struct Template {
    primitives: Vec<super::world::Primitive>,
    door_x: f64,
    viewpoint: [f64; 2],
    window: (f64, f64),
}

/// The office floor for `config`: its scene and layout.
pub(super) fn build(config: &IndoorConfig) -> (Scene, IndoorLayout) {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0x0ff1_ce00);
    let r = config.resolution;
    let snap = |v: f64| (v / r).round() * r;
    let h = config.wall_height;
    let t = (2.0 * r).max(0.08);
    let per_row = config.rooms.max(MIN_ROOMS).div_ceil(4);
    let w = snap(rng.random_range(3.1..3.6));
    let d = snap(rng.random_range(3.6..4.2));
    let cw = snap(rng.random_range(1.6..2.0));
    let len = per_row as f64 * w;
    let rows = [
        Row {
            y_min: -d,
            y_max: 0.0,
            inward: -1.0,
            outer: true,
            corridor: 0,
        },
        Row {
            y_min: cw,
            y_max: cw + d,
            inward: 1.0,
            outer: false,
            corridor: 0,
        },
        Row {
            y_min: cw + d,
            y_max: cw + 2.0 * d,
            inward: -1.0,
            outer: false,
            corridor: 1,
        },
        Row {
            y_min: 2.0 * cw + 2.0 * d,
            y_max: 2.0 * cw + 3.0 * d,
            inward: 1.0,
            outer: true,
            corridor: 1,
        },
    ];
    let templates = [
        office_template(w, d, snap, &mut rng),
        office_template(w, d, snap, &mut rng),
    ];
    // Unique rooms sit in the outer rows (they have windows); every other
    // room is an office of template 0 or 1, half each, shuffled.
    let n = 4 * per_row;
    let mut outer_slots: Vec<usize> = (0..n).filter(|i| rows[i / per_row].outer).collect();
    outer_slots.shuffle(&mut rng);
    let unique = [
        RoomKind::Kitchen,
        RoomKind::Living,
        RoomKind::Bathroom,
        RoomKind::Bathroom,
    ];
    let mut twins: Vec<usize> = (0..n - unique.len()).map(|i| i % 2).collect();
    twins.shuffle(&mut rng);
    let mut twins = twins.into_iter();

    let mut scene = Scene::new(super::building::INDOOR_CLASSES);
    let (x_lo, x_hi) = (-cw, len + cw);
    let (y_lo, y_hi) = (-d, 2.0 * cw + 3.0 * d);
    scene.add_box(FLOOR, [x_lo - t, y_lo - t, -r], [x_hi + t, y_hi + t, 0.0]);
    scene.add_box(
        CEILING,
        [x_lo - t, y_lo - t, h],
        [x_hi + t, y_hi + t, h + r],
    );
    let hall_y = [0.5 * cw, cw + 2.0 * d + 0.5 * cw];

    let mut rooms = Vec::with_capacity(n);
    let mut doors: [Vec<Opening>; 4] = Default::default();
    for i in 0..n {
        let row = &rows[i / per_row];
        let x0 = (i % per_row) as f64 * w;
        // Room frame to world: straight for rooms opening into +y, turned
        // by half a turn for rooms opening into -y.
        let to_world = |p: [f64; 2]| -> [f64; 2] {
            if row.inward > 0.0 {
                [x0 + p[0], row.y_min + p[1]]
            } else {
                [x0 + w - p[0], row.y_max - p[1]]
            }
        };
        let slot = outer_slots.iter().position(|&s| s == i);
        let (kind, twin, door_x_local, vp_local, window) = match slot {
            Some(k) if k < unique.len() => {
                let dx = snap(rng.random_range(0.8..w - 0.8));
                let depth = snap(rng.random_range(1.3..(d - 1.1).max(1.4)));
                let wx = snap(rng.random_range(0.9..w - 0.9));
                let ww = snap(rng.random_range(0.9..1.5f64).min(w - 1.2));
                (unique[k], None, dx, [dx, depth], (wx, ww))
            }
            _ => {
                let k = twins.next().unwrap_or(0);
                let tp = &templates[k];
                (
                    RoomKind::Office,
                    Some(k),
                    tp.door_x,
                    tp.viewpoint,
                    tp.window,
                )
            }
        };
        let door = to_world([door_x_local, 0.0]);
        let room = Room {
            kind,
            min: [x0, row.y_min],
            max: [x0 + w, row.y_max],
            door,
            inward: [0.0, row.inward],
            viewpoint: to_world(vp_local),
            hall_node: 0,
            twin,
        };
        doors[i / per_row].push(Opening::door(door[0]));
        // Side walls; the outer wall with its window.
        wall_y(&mut scene, x0, row.y_min, row.y_max, t, h, &[]);
        wall_y(&mut scene, x0 + w, row.y_min, row.y_max, t, h, &[]);
        let outer_y = if row.inward > 0.0 {
            row.y_max
        } else {
            row.y_min
        };
        if row.outer {
            let wc = to_world([window.0, d])[0];
            wall_x(
                &mut scene,
                outer_y,
                x0,
                x0 + w,
                t,
                h,
                &[Opening::window(wc, window.1)],
            );
        }
        match twin {
            Some(k) => {
                for p in &templates[k].primitives {
                    scene.add(p.label, place_shape(&p.shape, &to_world));
                }
            }
            None => {
                door_leaf(&mut scene, &room);
                let wc = to_world([window.0, d])[0];
                furniture::furnish(&mut scene, &room, (wc, window.1, outer_y), &mut rng);
            }
        }
        rooms.push(room);
    }
    // Corridor walls with the doors; the inner rows' shared back wall; the
    // ends of the loop, each with a window.
    let [a, b, c, dd] = doors;
    wall_x(&mut scene, 0.0, x_lo, x_hi, t, h, &a);
    wall_x(&mut scene, cw, 0.0, len, t, h, &b);
    wall_x(&mut scene, cw + d, 0.0, len, t, h, &[]);
    wall_x(&mut scene, cw + 2.0 * d, 0.0, len, t, h, &c);
    wall_x(&mut scene, 2.0 * cw + 2.0 * d, x_lo, x_hi, t, h, &dd);
    let mid = cw + d;
    for x in [x_lo, x_hi] {
        wall_y(
            &mut scene,
            x,
            0.0,
            2.0 * cw + 2.0 * d,
            t,
            h,
            &[Opening::window(mid, 1.0)],
        );
    }
    let corridor_walls = [0.0, cw, cw + 2.0 * d, 2.0 * cw + 2.0 * d];
    corridor_pictures(
        &mut scene,
        &rooms,
        [x_lo, x_hi],
        len,
        corridor_walls,
        t,
        &mut rng,
    );

    // Hall: a node in front of every door on its corridor's centre line and
    // one at each end of both corridors, in the cross corridors.
    let mut hall: Vec<[f64; 2]> = Vec::new();
    for (i, rm) in rooms.iter_mut().enumerate() {
        let row = &rows[i / per_row];
        rm.hall_node = hall.len();
        hall.push([rm.door[0], hall_y[row.corridor]]);
    }
    let ends: Vec<usize> = (0..4).map(|k| hall.len() + k).collect();
    for y in hall_y {
        hall.push([x_lo + 0.5 * cw, y]);
        hall.push([x_hi - 0.5 * cw, y]);
    }
    let mut hall_edges = Vec::new();
    for y in hall_y {
        let mut on: Vec<usize> = (0..hall.len()).filter(|&k| hall[k][1] == y).collect();
        on.sort_by(|&p, &q| hall[p][0].total_cmp(&hall[q][0]));
        hall_edges.extend(on.windows(2).map(|e| [e[0], e[1]]));
    }
    hall_edges.push([ends[0], ends[2]]);
    hall_edges.push([ends[1], ends[3]]);
    // The tour: along corridor 0 eastwards, back along corridor 1.
    let by_x = |corridor: usize, east: bool| {
        let mut v: Vec<usize> = (0..n)
            .filter(|&i| rows[i / per_row].corridor == corridor)
            .collect();
        v.sort_by(|&p, &q| rooms[p].door[0].total_cmp(&rooms[q].door[0]));
        if !east {
            v.reverse();
        }
        v
    };
    let mut tour = by_x(0, true);
    tour.extend(by_x(1, false));
    let layout = IndoorLayout {
        kind: WorldKind::Offices,
        rooms,
        hall,
        hall_edges,
        tour,
        wall_height: h,
    };
    (scene, layout)
}

/// An office furnished in its own frame (see [`Template`]): door leaf,
/// desk, screen, chair, shelving, cabinet, plant, lamp, picture.
fn office_template(w: f64, d: f64, snap: impl Fn(f64) -> f64, rng: &mut ChaCha8Rng) -> Template {
    let door_x = snap(rng.random_range(0.8..w - 0.8));
    let depth = snap(rng.random_range(1.3..(d - 1.1).max(1.4)));
    let wx = snap(rng.random_range(0.9..w - 0.9));
    let ww = snap(rng.random_range(0.9..1.5f64).min(w - 1.2));
    let rm = Room {
        kind: RoomKind::Office,
        min: [0.0, 0.0],
        max: [w, d],
        door: [door_x, 0.0],
        inward: [0.0, 1.0],
        viewpoint: [door_x, depth],
        hall_node: 0,
        twin: None,
    };
    let mut scene = Scene::new(super::building::INDOOR_CLASSES);
    door_leaf(&mut scene, &rm);
    furniture::furnish(&mut scene, &rm, (wx, ww, d), rng);
    Template {
        primitives: scene.primitives,
        door_x,
        viewpoint: rm.viewpoint,
        window: (wx, ww),
    }
}

/// `shape` moved by the floor map `to_world` (a translation, or a
/// translation and a half turn about z).
fn place_shape(shape: &Shape, to_world: &dyn Fn([f64; 2]) -> [f64; 2]) -> Shape {
    match *shape {
        Shape::Box(b) => {
            let p = to_world([b.min[0], b.min[1]]);
            let q = to_world([b.max[0], b.max[1]]);
            Shape::Box(Aabb::new([p[0], p[1], b.min[2]], [q[0], q[1], b.max[2]]))
        }
        Shape::Cylinder {
            x,
            y,
            radius,
            z0,
            z1,
        } => {
            let c = to_world([x, y]);
            Shape::Cylinder {
                x: c[0],
                y: c[1],
                radius,
                z0,
                z1,
            }
        }
        Shape::Ellipsoid { centre, radii } => {
            let c = to_world([centre[0], centre[1]]);
            Shape::Ellipsoid {
                centre: [c[0], c[1], centre[2]],
                radii,
            }
        }
    }
}

/// Pictures on the corridor walls (at y = `walls`: corridor 0's south and
/// north wall, corridor 1's south and north wall), away from the doors.
fn corridor_pictures(
    scene: &mut Scene,
    rooms: &[Room],
    [x_lo, x_hi]: [f64; 2],
    len: f64,
    walls: [f64; 4],
    t: f64,
    rng: &mut ChaCha8Rng,
) {
    for _ in 0..((x_hi - x_lo) / 2.5).ceil() as usize {
        let x = rng.random_range(x_lo + 0.5..x_hi - 0.5);
        let k = rng.random_range(0..4);
        let y = walls[k];
        // The inner rows' corridor walls end where the rows end.
        if (k == 1 || k == 2) && !(0.5..len - 0.5).contains(&x) {
            continue;
        }
        // A corridor's south wall shows its north face, and the reverse.
        let (face, dy) = if k % 2 == 0 {
            (y + t / 2.0, 0.03)
        } else {
            (y - t / 2.0, -0.03)
        };
        let clear = rooms
            .iter()
            .all(|rm| (rm.door[0] - x).abs() > 1.0 || (rm.door[1] - y).abs() > 0.5);
        if clear {
            scene.add_box(PICTURE, [x - 0.3, face, 1.3], [x + 0.3, face + dy, 1.8]);
        }
    }
}
