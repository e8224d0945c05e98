//! An open-plan home: one large living, dining and kitchen space with few
//! walls and long sight lines, and a bathroom and a bedroom off it.
//!
//! The great room is `[0, W] x [0, D]` (W 14 to 16 m, D 7 to 8.5 m). A
//! free aisle runs along its south side; north of it three zones (kitchen,
//! dining, living, west to east) hold their furniture as islands: a kitchen
//! run on the west wall with an island and stools, a dining table with
//! chairs under a pendant lamp, a sofa facing a TV across a rug. The two
//! side rooms lie south of the great room, their doors on the aisle. Each
//! zone has a free lane from the aisle to its viewpoint, as a walled room
//! has from its door. Metres, world z up, floor at z = 0.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::building::{
    CABINET, CEILING, COUNTER, CURTAIN, FLOOR, IndoorConfig, IndoorLayout, LAMP, Opening, PICTURE,
    RUG, Room, RoomKind, SINK, TABLE, TV, WorldKind, wall_x, wall_y,
};
use super::furniture::{self, Furnisher, Place, Rect, door_leaf};
use super::world::{Scene, Shape};

/// Depth of the free aisle along the great room's south wall, metres.
const AISLE: f64 = 1.5;

/// The open-plan home for `config`: its scene and layout.
pub(super) fn build(config: &IndoorConfig) -> (Scene, IndoorLayout) {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0x09e4_91a4);
    let r = config.resolution;
    let h = config.wall_height;
    let t = (2.0 * r).max(0.08);
    let depth = rng.random_range(7.0..8.5);
    let xk = rng.random_range(4.8..5.4);
    let xd = xk + rng.random_range(4.2..4.8);
    let width = xd + rng.random_range(5.0..5.8);
    let side_d = rng.random_range(3.6..4.2);
    // Side rooms: a bathroom and a bedroom, side by side, south of the
    // great room somewhere along it.
    let wb = rng.random_range(2.4..3.0);
    let wr = rng.random_range(3.8..4.4);
    let xs = rng.random_range(0.0..width - wb - wr);

    let mut scene = Scene::new(super::building::INDOOR_CLASSES);
    let (y_lo, y_hi) = (-side_d, depth);
    scene.add_box(FLOOR, [-t, y_lo - t, -r], [width + t, y_hi + t, 0.0]);
    scene.add_box(CEILING, [-t, y_lo - t, h], [width + t, y_hi + t, h + r]);

    // Zones: the kitchen, dining and living parts of the great room, each
    // with its lane from the aisle (x = entry) to a viewpoint.
    let vy = |rng: &mut ChaCha8Rng| rng.random_range(3.2..depth - 1.3);
    let e_k = rng.random_range(xk - 1.0..xk - 0.8);
    let e_d = xk + 0.85;
    let e_l = xd + 0.85;
    let zone = |kind, x0: f64, x1: f64, e: f64, v: f64| Room {
        kind,
        min: [x0, 0.0],
        max: [x1, depth],
        door: [e, AISLE],
        inward: [0.0, 1.0],
        viewpoint: [e, v],
        hall_node: 0,
        twin: None,
    };
    let zones = [
        zone(RoomKind::Kitchen, 0.0, xk, e_k, vy(&mut rng)),
        zone(RoomKind::Dining, xk, xd, e_d, vy(&mut rng)),
        zone(RoomKind::Living, xd, width, e_l, vy(&mut rng)),
    ];
    let side = |kind, x0: f64, x1: f64, rng: &mut ChaCha8Rng| {
        let dx = rng.random_range(x0 + 0.8..x1 - 0.8);
        let depth_in = rng.random_range(1.3..(side_d - 1.1).max(1.4));
        Room {
            kind,
            min: [x0, -side_d],
            max: [x1, 0.0],
            door: [dx, 0.0],
            inward: [0.0, -1.0],
            viewpoint: [dx, -depth_in],
            hall_node: 0,
            twin: None,
        }
    };
    let sides = [
        side(RoomKind::Bathroom, xs, xs + wb, &mut rng),
        side(RoomKind::Bedroom, xs + wb, xs + wb + wr, &mut rng),
    ];

    // Walls. South wall of the great room: the side rooms' doors, windows
    // where it is an outer wall; north wall: a window over the kitchen and
    // one over the dining table; east wall: a window in the living zone.
    let mut south: Vec<Opening> = sides.iter().map(|s| Opening::door(s.door[0])).collect();
    let mut windows: Vec<(f64, f64, usize)> = Vec::new(); // centre, width, wall (0 S, 1 N, 3 E)
    for (a, b) in [(0.0, xs), (xs + wb + wr, width)] {
        if b - a > 2.4 {
            let c = rng.random_range(a + 1.1..b - 1.1);
            let w = rng.random_range(0.9..1.5f64).min(b - a - 1.6);
            south.push(Opening::window(c, w));
            windows.push((c, w, 0));
        }
    }
    wall_x(&mut scene, 0.0, 0.0, width, t, h, &south);
    let north = [
        (rng.random_range(1.8..2.8), 1.2),
        (0.5 * (e_d + 0.75 + xd), 1.4),
    ];
    wall_x(
        &mut scene,
        depth,
        0.0,
        width,
        t,
        h,
        &north.map(|(c, w)| Opening::window(c, w)),
    );
    windows.extend(north.iter().map(|&(c, w)| (c, w, 1)));
    let east_c = rng.random_range(1.5 + AISLE..depth - 1.5);
    wall_y(&mut scene, 0.0, 0.0, depth, t, h, &[]);
    wall_y(
        &mut scene,
        width,
        0.0,
        depth,
        t,
        h,
        &[Opening::window(east_c, 1.4)],
    );
    windows.push((east_c, 1.4, 3));
    for s in &sides {
        let wx = rng.random_range(s.min[0] + 0.9..s.max[0] - 0.9);
        let ww = rng.random_range(0.9..1.5f64).min(s.max[0] - s.min[0] - 1.2);
        wall_x(
            &mut scene,
            s.min[1],
            s.min[0],
            s.max[0],
            t,
            h,
            &[Opening::window(wx, ww)],
        );
        wall_y(&mut scene, s.min[0], s.min[1], s.max[1], t, h, &[]);
        wall_y(&mut scene, s.max[0], s.min[1], s.max[1], t, h, &[]);
        door_leaf(&mut scene, s);
        furniture::furnish(&mut scene, s, (wx, ww, s.min[1]), &mut rng);
    }

    // Furniture of the great room. Everything claims its footprint among
    // the aisle, the lanes, the viewpoints and the space before windows.
    let mut taken = vec![Rect {
        min: [0.0, 0.0],
        max: [width, AISLE],
    }];
    for z in &zones {
        taken.push(Rect {
            min: [z.door[0] - 0.75, 0.0],
            max: [z.door[0] + 0.75, z.viewpoint[1] + 0.7],
        });
    }
    for &(c, w, wall) in &windows {
        let half = w / 2.0 + 0.1;
        taken.push(match wall {
            0 => Rect {
                min: [c - half, 0.0],
                max: [c + half, 0.5],
            },
            1 => Rect {
                min: [c - half, depth - 0.5],
                max: [c + half, depth],
            },
            _ => Rect {
                min: [width - 0.5, c - half],
                max: [width, c + half],
            },
        });
        // Curtains beside the windows of the great room.
        let (n, s) = match wall {
            0 => ([0.0, 1.0], 0.08),
            1 => ([0.0, -1.0], depth - 0.08),
            _ => ([-1.0, 0.0], width - 0.08),
        };
        for k in [-1.0, 1.0] {
            let a = c + k * (w / 2.0 + 0.12);
            let (p, q) = if n[0] == 0.0 {
                ([a - 0.15, s - 0.02, 0.3], [a + 0.15, s + 0.02, 2.3])
            } else {
                ([s - 0.02, a - 0.15, 0.3], [s + 0.02, a + 0.15, 2.3])
            };
            scene.add_box(CURTAIN, p, q);
        }
    }
    let mut f = Furnisher::new(&zones[0], taken);
    kitchen_zone(&mut scene, &mut f, depth, &mut rng);
    let mut f = Furnisher::new(&zones[1], f.taken);
    dining_zone(&mut scene, &mut f, depth, h, &mut rng);
    let mut f = Furnisher::new(&zones[2], f.taken);
    living_zone(&mut scene, &mut f, depth, &mut rng);

    // Hall: one node on the aisle's centre line before each zone and each
    // side room, joined west to east; the tour follows them.
    let rooms: Vec<Room> = zones.into_iter().chain(sides).collect();
    let layout = IndoorLayout::along_line(WorldKind::OpenPlan, rooms, 0.5 * AISLE, h);
    (scene, layout)
}

/// A kitchen run on the west wall, an island with stools, a plant, a lamp
/// and a picture on the north wall.
fn kitchen_zone(scene: &mut Scene, f: &mut Furnisher, depth: f64, rng: &mut ChaCha8Rng) {
    let yc = 0.5 * (AISLE + depth) + rng.random_range(-0.3..0.3);
    let run = (depth - AISLE - 1.2).min(3.2);
    let p = Place {
        o: [0.06, yc],
        u: [0.0, -1.0],
        n: [1.0, 0.0],
    };
    if f.claim(p.rect(-run / 2.0, run / 2.0, 0.0, 0.68)) {
        furniture::kitchen_run(scene, &p, run, rng);
    }
    // The island: a counter with a sink, stools on its east side.
    let (x0, x1) = (1.75, 2.65);
    let island = Rect {
        min: [x0, yc - 0.9],
        max: [x1, yc + 0.9],
    };
    if f.claim(island) {
        scene.add_box(COUNTER, [x0, yc - 0.9, 0.0], [x1, yc + 0.9, 0.9]);
        scene.add_box(SINK, [x0 + 0.2, yc - 0.3, 0.86], [x1 - 0.2, yc + 0.3, 0.93]);
        for dy in [-0.5, 0.1] {
            let stool = Place {
                o: [x1 + 0.55, yc + dy + 0.2],
                u: [0.0, 1.0],
                n: [-1.0, 0.0],
            };
            if f.claim(stool.rect(-0.22, 0.22, 0.0, 0.44)) {
                furniture::chair(scene, &stool);
            }
        }
    }
    furniture::plant_and_lamp(scene, f, rng);
    picture_north(scene, f, depth, rng);
}

/// A dining table with six chairs under a pendant lamp, shelving, a plant,
/// a lamp and a picture on the north wall.
fn dining_zone(scene: &mut Scene, f: &mut Furnisher, depth: f64, h: f64, rng: &mut ChaCha8Rng) {
    let rm = f.rm;
    let cx = 0.5 * (rm.door[0] + 0.75 + rm.max[0]) + rng.random_range(-0.2..0.2);
    let cy = 0.5 * (AISLE + depth) + rng.random_range(-0.3..0.3);
    // Table 1.0 m across x, 1.8 m along y; three chairs on each long side.
    if f.claim(Rect {
        min: [cx - 1.05, cy - 1.0],
        max: [cx + 1.05, cy + 1.0],
    }) {
        let p = Place {
            o: [cx - 0.5, cy],
            u: [0.0, -1.0],
            n: [1.0, 0.0],
        };
        furniture::table(scene, &p, 1.8, 1.0, 0.75, TABLE);
        for dy in [-0.6, 0.0, 0.6] {
            for s in [-1.0, 1.0] {
                let chair = Place {
                    o: [cx + s * 0.95, cy + dy],
                    u: [0.0, s],
                    n: [-s, 0.0],
                };
                furniture::chair(scene, &chair);
            }
        }
        // Pendant lamp over the table.
        for (radius, z0, z1) in [(0.01, 1.75, h), (0.25, 1.55, 1.75)] {
            scene.add(
                LAMP,
                Shape::Cylinder {
                    x: cx,
                    y: cy,
                    radius,
                    z0,
                    z1,
                },
            );
        }
    }
    if let Some(p) = f.on_walls(rng, &[1], 0.9, 0.35) {
        furniture::shelving(scene, &p, 0.9, 0.35, 1.9);
    }
    furniture::plant_and_lamp(scene, f, rng);
    picture_north(scene, f, depth, rng);
}

/// A TV on a cabinet on the north wall, a sofa facing it across a rug
/// with a coffee table, shelving on the east wall, a plant and a lamp.
fn living_zone(scene: &mut Scene, f: &mut Furnisher, depth: f64, rng: &mut ChaCha8Rng) {
    let rm = f.rm;
    // Centred between the lane and the strip before the east window.
    let cx = 0.5 * (rm.door[0] + 0.75 + rm.max[0] - 0.5) + rng.random_range(-0.15..0.15);
    let tv = Place {
        o: [cx, depth - 0.06],
        u: [-1.0, 0.0],
        n: [0.0, -1.0],
    };
    if f.claim(tv.rect(-0.7, 0.7, 0.0, 0.45)) {
        scene.add(CABINET, tv.bx(-0.7, 0.7, 0.0, 0.45, 0.0, 0.55));
        scene.add(TV, tv.bx(-0.55, 0.55, 0.1, 0.16, 0.6, 1.25));
        scene.add(TV, tv.bx(-0.1, 0.1, 0.05, 0.25, 0.55, 0.6));
    }
    let sofa_y = (depth - 0.5 - 2.6 - 0.95).max(AISLE + 0.1);
    let sofa = Place {
        o: [cx, sofa_y],
        u: [1.0, 0.0],
        n: [0.0, 1.0],
    };
    if f.claim(sofa.rect(-1.3, 1.3, 0.0, 2.3)) {
        furniture::sofa(scene, &sofa, 2.1, 0.95);
        scene.add(RUG, sofa.bx(-1.3, 1.3, 0.3, 2.3, 0.0, 0.012));
        furniture::table(scene, &sofa.shift(0.0, 1.3), 1.0, 0.55, 0.45, TABLE);
    }
    if let Some(p) = f.on_walls(rng, &[3], 0.9, 0.35) {
        furniture::shelving(scene, &p, 0.9, 0.35, 1.9);
    }
    furniture::plant_and_lamp(scene, f, rng);
    picture_north(scene, f, depth, rng);
}

/// A picture on the north wall within the zone, clear of windows and of
/// anything tall already there.
fn picture_north(scene: &mut Scene, f: &mut Furnisher, depth: f64, rng: &mut ChaCha8Rng) {
    let rm = f.rm;
    for _ in 0..10 {
        let w = rng.random_range(0.5..0.9);
        let x = rng.random_range(rm.min[0] + 0.6..rm.max[0] - 0.6);
        let p = Place {
            o: [x, depth - 0.05],
            u: [-1.0, 0.0],
            n: [0.0, -1.0],
        };
        if f.claim(p.rect(-w / 2.0, w / 2.0, 0.0, 0.1)) {
            let z0 = rng.random_range(1.3..1.6);
            scene.add(
                PICTURE,
                p.bx(-w / 2.0, w / 2.0, 0.0, 0.03, z0, z0 + w * 0.75),
            );
            return;
        }
    }
}
