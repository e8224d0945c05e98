//! The corridor apartment, the benchmark's first world: rooms (living
//! room, kitchen, bathroom, bedroom, office, then more of them) line both
//! sides of a straight corridor. Every room has a door onto the corridor
//! (an open door leaf stands inside it) and a window in its outer wall.
//! Metres, world z up, floor at z = 0.

use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::building::*;
use super::furniture::{door_leaf, furnish};
use super::world::Scene;

/// The corridor apartment for `config`: its scene and layout.
pub(super) fn build(config: &IndoorConfig) -> (Scene, IndoorLayout) {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0x1d00_5eed);
    let h = config.wall_height;
    let t = (2.0 * config.resolution).max(0.08);
    let n = config.rooms.max(1);
    let kinds = room_kinds(n, &mut rng);

    let cw = rng.random_range(1.4..1.7);
    let (rooms, x_side) = lay_out_rooms(&kinds, cw, &mut rng);
    let length = x_side[0].max(x_side[1]);
    let mut scene = Scene::new(INDOOR_CLASSES);
    let y_min = rooms.iter().map(|r| r.min[1]).fold(0.0f64, f64::min);
    let y_max = rooms.iter().map(|r| r.max[1]).fold(cw, f64::max);
    let r = config.resolution;
    scene.add_box(FLOOR, [-t, y_min - t, -r], [length + t, y_max + t, 0.0]);
    scene.add_box(CEILING, [-t, y_min - t, h], [length + t, y_max + t, h + r]);

    corridor_walls(&mut scene, &rooms, x_side, cw, [y_min, y_max], t, h);
    for rm in &rooms {
        let outer_y = if rm.inward[1] < 0.0 {
            rm.min[1]
        } else {
            rm.max[1]
        };
        let wx = rng.random_range(rm.min[0] + 0.9..rm.max[0] - 0.9);
        let ww = rng
            .random_range(0.9..1.5f64)
            .min(rm.max[0] - rm.min[0] - 1.2);
        wall_x(
            &mut scene,
            outer_y,
            rm.min[0],
            rm.max[0],
            t,
            h,
            &[Opening::window(wx, ww)],
        );
        wall_y(&mut scene, rm.min[0], rm.min[1], rm.max[1], t, h, &[]);
        wall_y(&mut scene, rm.max[0], rm.min[1], rm.max[1], t, h, &[]);
        door_leaf(&mut scene, rm);
        let window = (wx, ww, outer_y);
        furnish(&mut scene, rm, window, &mut rng);
    }
    corridor_pictures(&mut scene, &rooms, length, cw, t, &mut rng);
    // Hall: a node on the corridor's centre line before every door,
    // joined in order along the corridor; the tour walks it end to end.
    let layout = IndoorLayout::along_line(WorldKind::Corridor, rooms, 0.5 * cw, h);
    (scene, layout)
}

/// The kinds of `n` rooms: one of each kind first, then bedrooms, offices,
/// bathrooms or living rooms at random; shuffled.
fn room_kinds(n: usize, rng: &mut ChaCha8Rng) -> Vec<RoomKind> {
    let mut kinds = vec![
        RoomKind::Living,
        RoomKind::Kitchen,
        RoomKind::Bathroom,
        RoomKind::Bedroom,
        RoomKind::Office,
    ];
    let extra = [
        RoomKind::Bedroom,
        RoomKind::Office,
        RoomKind::Bathroom,
        RoomKind::Living,
    ];
    while kinds.len() < n {
        kinds.push(extra[rng.random_range(0..extra.len())]);
    }
    kinds.truncate(n);
    kinds.shuffle(rng);
    kinds
}

/// The rooms along both sides of a corridor of width `cw` (even rooms
/// south, odd rooms north), each with its door on the corridor and a
/// viewpoint inside; and where each side of the corridor ends.
fn lay_out_rooms(kinds: &[RoomKind], cw: f64, rng: &mut ChaCha8Rng) -> (Vec<Room>, [f64; 2]) {
    let mut rooms = Vec::new();
    let mut x_side = [0.0f64, 0.0];
    for (i, &kind) in kinds.iter().enumerate() {
        let side = i % 2; // 0: south (y < 0), 1: north (y > cw)
        let (w, d): (f64, f64) = match kind {
            RoomKind::Bathroom => (rng.random_range(2.3..3.0), rng.random_range(2.6..3.2)),
            RoomKind::Living => (rng.random_range(4.0..5.0), rng.random_range(3.8..4.6)),
            _ => (rng.random_range(3.2..4.2), rng.random_range(3.4..4.4)),
        };
        let x0 = x_side[side];
        let x1 = x0 + w;
        x_side[side] = x1;
        let (y0, y1, door_y, inward) = if side == 0 {
            (-d, 0.0, 0.0, [0.0, -1.0])
        } else {
            (cw, cw + d, cw, [0.0, 1.0])
        };
        let door_x = rng.random_range(x0 + 0.8..x1 - 0.8);
        let depth_in = rng.random_range(1.3..(d - 1.1).max(1.4));
        let viewpoint = [door_x, door_y + inward[1] * depth_in];
        rooms.push(Room {
            kind,
            min: [x0, y0],
            max: [x1, y1],
            door: [door_x, door_y],
            inward,
            viewpoint,
            hall_node: 0,
            twin: None,
        });
    }
    (rooms, x_side)
}

/// The corridor's walls: its long walls with the rooms' doors, its ends
/// (a window at the far one), and blind walls where one side is shorter.
fn corridor_walls(
    scene: &mut Scene,
    rooms: &[Room],
    x_side: [f64; 2],
    cw: f64,
    [y_min, y_max]: [f64; 2],
    t: f64,
    h: f64,
) {
    let length = x_side[0].max(x_side[1]);
    // Corridor walls with the doors of the rooms on each side.
    for (side, y) in [(0usize, 0.0), (1, cw)] {
        let doors: Vec<Opening> = rooms
            .iter()
            .enumerate()
            .filter(|(i, _)| i % 2 == side)
            .map(|(_, rm)| Opening::door(rm.door[0]))
            .collect();
        wall_x(scene, y, 0.0, length, t, h, &doors);
    }
    wall_y(scene, 0.0, 0.0, cw, t, h, &[]);
    wall_y(
        scene,
        length,
        0.0,
        cw,
        t,
        h,
        &[Opening::window(0.5 * cw, 0.8)],
    );
    // Blind walls where one side of the corridor is shorter than the other.
    for (side, &x_end) in x_side.iter().enumerate() {
        if x_end < length - 1e-9 {
            let (ya, yb) = if side == 0 { (y_min, 0.0) } else { (cw, y_max) };
            wall_y(scene, x_end, ya, yb, t, h, &[]);
        }
    }
}

/// Pictures along the corridor walls, away from the doors.
fn corridor_pictures(
    scene: &mut Scene,
    rooms: &[Room],
    length: f64,
    cw: f64,
    t: f64,
    rng: &mut ChaCha8Rng,
) {
    for _ in 0..(length / 3.0).ceil() as usize {
        let x = rng.random_range(0.5..(length - 0.5).max(0.6));
        let side_y = if rng.random_bool(0.5) {
            t / 2.0
        } else {
            cw - t / 2.0
        };
        let clear = rooms
            .iter()
            .all(|rm| (rm.door[0] - x).abs() > 1.0 || (rm.door[1] - side_y).abs() > 0.5);
        if clear {
            let dy = if side_y < cw / 2.0 { 0.03 } else { -0.03 };
            scene.add_box(PICTURE, [x - 0.3, side_y, 1.3], [x + 0.3, side_y + dy, 1.8]);
        }
    }
}
