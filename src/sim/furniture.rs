//! Furniture: where a piece may stand in a room (against a wall, anywhere
//! free, clear of the door's strip and the viewpoint) and the pieces
//! themselves, built from boxes, cylinders and ellipsoids. Rooms are
//! furnished by kind. Shared by every indoor layout ([`super::indoor`]).
//! Metres, world z up, floor at z = 0.

use rand::Rng;
use rand_chacha::ChaCha8Rng;

use super::building::*;
use super::world::{Aabb, Scene, Shape};

/// A local frame on the floor: origin at the wall-side centre of an object,
/// `u` along the wall, `n` into the room (axis-aligned unit vectors).
#[derive(Clone, Copy)]
pub(super) struct Place {
    pub(super) o: [f64; 2],
    pub(super) u: [f64; 2],
    pub(super) n: [f64; 2],
}

impl Place {
    pub(super) fn at(&self, a: f64, b: f64) -> [f64; 2] {
        [
            self.o[0] + a * self.u[0] + b * self.n[0],
            self.o[1] + a * self.u[1] + b * self.n[1],
        ]
    }
    /// Box spanning `[a0, a1]` along u, `[b0, b1]` along n, `[z0, z1]`.
    pub(super) fn bx(&self, a0: f64, a1: f64, b0: f64, b1: f64, z0: f64, z1: f64) -> Shape {
        let p = self.at(a0, b0);
        let q = self.at(a1, b1);
        Shape::Box(Aabb::new([p[0], p[1], z0], [q[0], q[1], z1]))
    }
    /// Footprint rectangle of `[a0, a1] x [b0, b1]`.
    pub(super) fn rect(&self, a0: f64, a1: f64, b0: f64, b1: f64) -> Rect {
        let p = self.at(a0, b0);
        let q = self.at(a1, b1);
        Rect {
            min: [p[0].min(q[0]), p[1].min(q[1])],
            max: [p[0].max(q[0]), p[1].max(q[1])],
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub(super) struct Rect {
    pub(super) min: [f64; 2],
    pub(super) max: [f64; 2],
}

impl Rect {
    pub(super) fn overlaps(&self, o: &Rect) -> bool {
        self.min[0] < o.max[0]
            && o.min[0] < self.max[0]
            && self.min[1] < o.max[1]
            && o.min[1] < self.max[1]
    }
}

/// Which wall of a room: 0 south (y = min), 1 north, 2 west (x = min), 3 east.
pub(super) fn wall_place(rm: &Room, wall: usize, along: f64, inset: f64) -> Place {
    match wall {
        0 => Place {
            o: [along, rm.min[1] + inset],
            u: [1.0, 0.0],
            n: [0.0, 1.0],
        },
        1 => Place {
            o: [along, rm.max[1] - inset],
            u: [-1.0, 0.0],
            n: [0.0, -1.0],
        },
        2 => Place {
            o: [rm.min[0] + inset, along],
            u: [0.0, -1.0],
            n: [1.0, 0.0],
        },
        _ => Place {
            o: [rm.max[0] - inset, along],
            u: [0.0, 1.0],
            n: [-1.0, 0.0],
        },
    }
}

pub(super) struct Furnisher<'a> {
    pub(super) rm: &'a Room,
    /// Footprints already occupied (or kept free).
    pub(super) taken: Vec<Rect>,
    /// Wall index of the outer (window) wall.
    window_wall: usize,
    window: (f64, f64),
}

impl<'a> Furnisher<'a> {
    /// A furnisher for a room without walls of its own (a zone of an open
    /// plan): no window wall, `taken` already occupied.
    pub(super) fn new(rm: &'a Room, taken: Vec<Rect>) -> Self {
        Furnisher {
            rm,
            taken,
            window_wall: usize::MAX,
            window: (0.0, 0.0),
        }
    }
}

impl Furnisher<'_> {
    /// Finds a spot against a wall for a `w` x `d` footprint; `side_only`
    /// restricts to the two walls without door or window (tall furniture).
    pub(super) fn against_wall(
        &mut self,
        rng: &mut ChaCha8Rng,
        w: f64,
        d: f64,
        side_only: bool,
    ) -> Option<Place> {
        for _ in 0..40 {
            let wall = if side_only {
                2 + rng.random_range(0..2)
            } else {
                rng.random_range(0..4)
            };
            let (lo, hi) = if wall < 2 {
                (self.rm.min[0], self.rm.max[0])
            } else {
                (self.rm.min[1], self.rm.max[1])
            };
            if hi - lo < w + 0.1 {
                continue;
            }
            let along = rng.random_range(lo + w / 2.0 + 0.05..hi - w / 2.0 - 0.05);
            let p = wall_place(self.rm, wall, along, 0.06);
            let rect = p.rect(-w / 2.0, w / 2.0, 0.0, d);
            if wall == self.window_wall
                && (along - self.window.0).abs() < (w + self.window.1) / 2.0
                && d > 0.0
                && !side_only
            {
                // Low furniture only under the window: the caller decides height;
                // keep windows visible by skipping them altogether.
                continue;
            }
            if self.taken.iter().all(|t| !t.overlaps(&rect)) {
                self.taken.push(rect);
                return Some(p);
            }
        }
        None
    }

    /// Occupies `rect` if nothing taken overlaps it; whether it did.
    pub(super) fn claim(&mut self, rect: Rect) -> bool {
        let free = self.taken.iter().all(|t| !t.overlaps(&rect));
        if free {
            self.taken.push(rect);
        }
        free
    }

    /// A free spot for a `w` x `d` footprint against one of `walls` (see
    /// [`wall_place`] for their numbers).
    pub(super) fn on_walls(
        &mut self,
        rng: &mut ChaCha8Rng,
        walls: &[usize],
        w: f64,
        d: f64,
    ) -> Option<Place> {
        if walls.is_empty() {
            return None;
        }
        for _ in 0..40 {
            let wall = walls[rng.random_range(0..walls.len())];
            let (lo, hi) = if wall < 2 {
                (self.rm.min[0], self.rm.max[0])
            } else {
                (self.rm.min[1], self.rm.max[1])
            };
            if hi - lo < w + 0.1 {
                return None;
            }
            let along = rng.random_range(lo + w / 2.0 + 0.05..hi - w / 2.0 - 0.05);
            let p = wall_place(self.rm, wall, along, 0.06);
            if self.claim(p.rect(-w / 2.0, w / 2.0, 0.0, d)) {
                return Some(p);
            }
        }
        None
    }

    /// A free spot anywhere in the room for a `w` x `d` footprint.
    pub(super) fn anywhere(&mut self, rng: &mut ChaCha8Rng, w: f64, d: f64) -> Option<[f64; 2]> {
        for _ in 0..40 {
            let lo = [
                self.rm.min[0] + w / 2.0 + 0.5,
                self.rm.min[1] + d / 2.0 + 0.5,
            ];
            let hi = [
                self.rm.max[0] - w / 2.0 - 0.5,
                self.rm.max[1] - d / 2.0 - 0.5,
            ];
            if hi[0] <= lo[0] || hi[1] <= lo[1] {
                return None;
            }
            let c = [
                rng.random_range(lo[0]..hi[0]),
                rng.random_range(lo[1]..hi[1]),
            ];
            let rect = Rect {
                min: [c[0] - w / 2.0, c[1] - d / 2.0],
                max: [c[0] + w / 2.0, c[1] + d / 2.0],
            };
            if self.taken.iter().all(|t| !t.overlaps(&rect)) {
                self.taken.push(rect);
                return Some(c);
            }
        }
        None
    }
}

/// The open door leaf of `rm`, against the jamb, swung into the room.
pub(super) fn door_leaf(scene: &mut Scene, rm: &Room) {
    let dx0 = rm.door[0] - 0.45;
    let (b0, b1) = (rm.door[1], rm.door[1] + rm.inward[1] * 0.85);
    scene.add_box(DOOR, [dx0 - 0.04, b0.min(b1), 0.0], [dx0, b0.max(b1), 2.05]);
}

/// Furnishes `rm` by its kind; `window` is the window's centre and width
/// along the outer wall and that wall's y.
pub(super) fn furnish(scene: &mut Scene, rm: &Room, window: (f64, f64, f64), rng: &mut ChaCha8Rng) {
    let south = rm.inward[1] < 0.0;
    // The door is on the corridor side; the window on the opposite wall.
    let window_wall = if south { 0 } else { 1 };
    let mut f = Furnisher {
        rm,
        taken: Vec::new(),
        window_wall,
        window: (window.0, window.1),
    };
    // Keep the strip from the door to beyond the viewpoint free.
    let (ya, yb) = (rm.door[1], rm.viewpoint[1] + rm.inward[1] * 0.7);
    f.taken.push(Rect {
        min: [rm.door[0] - 0.75, ya.min(yb)],
        max: [rm.door[0] + 0.75, ya.max(yb)],
    });
    f.taken.push(Rect {
        min: [rm.viewpoint[0] - 0.7, rm.viewpoint[1] - 0.7],
        max: [rm.viewpoint[0] + 0.7, rm.viewpoint[1] + 0.7],
    });
    // Curtains either side of the window in living rooms and bedrooms.
    if matches!(rm.kind, RoomKind::Living | RoomKind::Bedroom) {
        let wy = window.2 + rm.inward[1] * 0.08;
        for s in [-1.0, 1.0] {
            let x = window.0 + s * (window.1 / 2.0 + 0.12);
            scene.add_box(
                CURTAIN,
                [x - 0.15, wy - 0.02, 0.3],
                [x + 0.15, wy + 0.02, 2.3],
            );
        }
    }
    match rm.kind {
        RoomKind::Living => furnish_living(scene, &mut f, rng),
        RoomKind::Kitchen => furnish_kitchen(scene, &mut f, rng),
        RoomKind::Bathroom => furnish_bathroom(scene, &mut f, rng),
        RoomKind::Bedroom => furnish_bedroom(scene, &mut f, rng),
        RoomKind::Office => furnish_office(scene, &mut f, rng),
        // Dining areas are zones of an open plan, furnished there.
        RoomKind::Dining => furnish_kitchen(scene, &mut f, rng),
    }
}

/// A sofa with a coffee table on a rug, a TV on a cabinet, shelving, a plant, a lamp and pictures.
fn furnish_living(scene: &mut Scene, f: &mut Furnisher, rng: &mut ChaCha8Rng) {
    if let Some(p) = f.against_wall(rng, 2.1, 0.95, true) {
        sofa(scene, &p, 2.1, 0.95);
        // Coffee table in front of the sofa, rug under both.
        scene.add(RUG, p.bx(-1.3, 1.3, 0.3, 2.2, 0.0, 0.012));
        table(scene, &p.shift(0.0, 1.3), 1.0, 0.55, 0.45, TABLE);
    }
    if let Some(p) = f.against_wall(rng, 1.4, 0.45, false) {
        scene.add(CABINET, p.bx(-0.7, 0.7, 0.0, 0.45, 0.0, 0.55));
        scene.add(TV, p.bx(-0.55, 0.55, 0.1, 0.16, 0.6, 1.25));
        scene.add(TV, p.bx(-0.1, 0.1, 0.05, 0.25, 0.55, 0.6));
    }
    if let Some(p) = f.against_wall(rng, 0.9, 0.35, true) {
        shelving(scene, &p, 0.9, 0.35, 1.9);
    }
    plant_and_lamp(scene, f, rng);
    pictures(scene, f, rng, 2);
}

/// A kitchen run along a wall, a dining table with chairs, a plant, a lamp and a picture.
fn furnish_kitchen(scene: &mut Scene, f: &mut Furnisher, rng: &mut ChaCha8Rng) {
    let rm = f.rm;
    let run = (rm.max[1] - rm.min[1] - 1.0).min(3.0);
    if let Some(p) = f.against_wall(rng, run, 0.62, true) {
        kitchen_run(scene, &p, run, rng);
    }
    if let Some(c) = f.anywhere(rng, 1.8, 1.6) {
        let p = Place {
            o: [c[0], c[1] - 0.4],
            u: [1.0, 0.0],
            n: [0.0, 1.0],
        };
        table(scene, &p, 1.2, 0.8, 0.75, TABLE);
        chair(
            scene,
            &Place {
                o: [c[0] - 0.3, c[1] - 0.75],
                u: [1.0, 0.0],
                n: [0.0, 1.0],
            },
        );
        chair(
            scene,
            &Place {
                o: [c[0] + 0.3, c[1] + 0.75],
                u: [-1.0, 0.0],
                n: [0.0, -1.0],
            },
        );
        if rng.random_bool(0.5) {
            chair(
                scene,
                &Place {
                    o: [c[0] + 0.3, c[1] - 0.75],
                    u: [1.0, 0.0],
                    n: [0.0, 1.0],
                },
            );
        }
    }
    plant_and_lamp(scene, f, rng);
    pictures(scene, f, rng, 1);
}

/// A bathtub, a toilet, a sink under a mirror on a cabinet, towels.
fn furnish_bathroom(scene: &mut Scene, f: &mut Furnisher, rng: &mut ChaCha8Rng) {
    if let Some(p) = f.against_wall(rng, 1.7, 0.75, true) {
        scene.add(BATHTUB, p.bx(-0.85, 0.85, 0.0, 0.75, 0.0, 0.55));
    }
    if let Some(p) = f.against_wall(rng, 0.45, 0.7, false) {
        scene.add(TOILET, p.bx(-0.2, 0.2, 0.0, 0.2, 0.35, 0.8));
        let c = p.at(0.0, 0.45);
        scene.add(
            TOILET,
            Shape::Cylinder {
                x: c[0],
                y: c[1],
                radius: 0.2,
                z0: 0.0,
                z1: 0.42,
            },
        );
    }
    if let Some(p) = f.against_wall(rng, 1.3, 0.5, true) {
        scene.add(CABINET, p.bx(-0.32, 0.32, 0.0, 0.48, 0.0, 0.8));
        scene.add(SINK, p.bx(-0.3, 0.3, 0.02, 0.5, 0.8, 0.9));
        scene.add(MIRROR, p.bx(-0.3, 0.3, 0.0, 0.02, 1.1, 1.8));
        scene.add(TOWEL, p.bx(0.4, 0.65, 0.0, 0.04, 0.8, 1.4));
    }
    if let Some(p) = f.against_wall(rng, 0.6, 0.05, true) {
        scene.add(TOWEL, p.bx(-0.3, 0.3, 0.0, 0.05, 0.9, 1.6));
    }
}

/// A bed between nightstands with lamps, a wardrobe, a rug, pictures, a plant and a lamp.
fn furnish_bedroom(scene: &mut Scene, f: &mut Furnisher, rng: &mut ChaCha8Rng) {
    if let Some(p) = f.against_wall(rng, 2.8, 2.1, true) {
        bed(scene, &p, 1.6, 2.05);
        for s in [-1.0, 1.0] {
            let q = p.shift(s * 1.1, 0.0);
            scene.add(NIGHTSTAND, q.bx(-0.22, 0.22, 0.0, 0.4, 0.0, 0.55));
            let c = q.at(0.0, 0.2);
            scene.add(
                LAMP,
                Shape::Cylinder {
                    x: c[0],
                    y: c[1],
                    radius: 0.06,
                    z0: 0.55,
                    z1: 0.75,
                },
            );
            scene.add(
                LAMP,
                Shape::Cylinder {
                    x: c[0],
                    y: c[1],
                    radius: 0.14,
                    z0: 0.75,
                    z1: 0.95,
                },
            );
        }
    }
    if let Some(p) = f.against_wall(rng, 1.2, 0.6, true) {
        scene.add(WARDROBE, p.bx(-0.6, 0.6, 0.0, 0.6, 0.0, 2.0));
    }
    if let Some(c) = f.anywhere(rng, 1.6, 1.0) {
        scene.add_box(
            RUG,
            [c[0] - 0.8, c[1] - 0.5, 0.0],
            [c[0] + 0.8, c[1] + 0.5, 0.012],
        );
    }
    pictures(scene, f, rng, 2);
    plant_and_lamp(scene, f, rng);
}

/// A desk with a screen and a chair, shelving, a cabinet, a plant, a lamp and a picture.
fn furnish_office(scene: &mut Scene, f: &mut Furnisher, rng: &mut ChaCha8Rng) {
    if let Some(p) = f.against_wall(rng, 1.4, 1.3, false) {
        table(scene, &p, 1.4, 0.7, 0.74, DESK);
        scene.add(TV, p.bx(-0.3, 0.3, 0.12, 0.16, 0.85, 1.2));
        scene.add(TV, p.bx(-0.08, 0.08, 0.1, 0.22, 0.74, 0.85));
        chair(
            scene,
            &Place {
                o: p.at(0.0, 1.2),
                u: [-p.u[0], -p.u[1]],
                n: [-p.n[0], -p.n[1]],
            },
        );
    }
    for _ in 0..2 {
        if let Some(p) = f.against_wall(rng, 0.9, 0.35, true) {
            shelving(scene, &p, 0.9, 0.35, 1.9);
        }
    }
    if let Some(p) = f.against_wall(rng, 0.8, 0.45, false) {
        scene.add(CABINET, p.bx(-0.4, 0.4, 0.0, 0.45, 0.0, 0.75));
    }
    plant_and_lamp(scene, f, rng);
    pictures(scene, f, rng, 1);
}

impl Place {
    /// The same frame moved by `a` along u and `b` along n.
    pub(super) fn shift(&self, a: f64, b: f64) -> Place {
        Place {
            o: self.at(a, b),
            ..*self
        }
    }
}

pub(super) fn table(scene: &mut Scene, p: &Place, w: f64, d: f64, h: f64, label: u16) {
    scene.add(label, p.bx(-w / 2.0, w / 2.0, 0.0, d, h - 0.04, h));
    for (a, b) in [
        (-w / 2.0 + 0.03, 0.03),
        (w / 2.0 - 0.08, 0.03),
        (-w / 2.0 + 0.03, d - 0.08),
        (w / 2.0 - 0.08, d - 0.08),
    ] {
        scene.add(label, p.bx(a, a + 0.05, b, b + 0.05, 0.0, h - 0.04));
    }
}

/// A chair whose back is at the frame origin, facing along n.
pub(super) fn chair(scene: &mut Scene, p: &Place) {
    scene.add(CHAIR, p.bx(-0.22, 0.22, 0.0, 0.44, 0.42, 0.47));
    scene.add(CHAIR, p.bx(-0.22, 0.22, 0.0, 0.05, 0.47, 0.9));
    for (a, b) in [(-0.22, 0.0), (0.18, 0.0), (-0.22, 0.4), (0.18, 0.4)] {
        scene.add(CHAIR, p.bx(a, a + 0.04, b, b + 0.04, 0.0, 0.42));
    }
}

pub(super) fn sofa(scene: &mut Scene, p: &Place, w: f64, d: f64) {
    scene.add(SOFA, p.bx(-w / 2.0, w / 2.0, 0.0, d, 0.0, 0.4));
    scene.add(SOFA, p.bx(-w / 2.0, w / 2.0, 0.0, 0.2, 0.4, 0.85));
    scene.add(SOFA, p.bx(-w / 2.0, -w / 2.0 + 0.15, 0.2, d, 0.4, 0.62));
    scene.add(SOFA, p.bx(w / 2.0 - 0.15, w / 2.0, 0.2, d, 0.4, 0.62));
    let inner = w - 0.3;
    for i in 0..3 {
        let a0 = -inner / 2.0 + i as f64 * inner / 3.0 + 0.02;
        let a1 = a0 + inner / 3.0 - 0.04;
        scene.add(CUSHION, p.bx(a0, a1, 0.2, d - 0.05, 0.4, 0.5));
        if i != 1 {
            scene.add(CUSHION, p.bx(a0 + 0.1, a1 - 0.1, 0.2, 0.32, 0.5, 0.85));
        }
    }
}

pub(super) fn bed(scene: &mut Scene, p: &Place, w: f64, d: f64) {
    scene.add(BED, p.bx(-w / 2.0, w / 2.0, 0.0, d, 0.0, 0.5));
    scene.add(BED, p.bx(-w / 2.0, w / 2.0, 0.0, 0.08, 0.0, 1.05));
    scene.add(CUSHION, p.bx(-w / 2.0 + 0.1, -0.05, 0.12, 0.5, 0.5, 0.64));
    scene.add(CUSHION, p.bx(0.05, w / 2.0 - 0.1, 0.12, 0.5, 0.5, 0.64));
}

pub(super) fn shelving(scene: &mut Scene, p: &Place, w: f64, d: f64, h: f64) {
    scene.add(SHELVING, p.bx(-w / 2.0, -w / 2.0 + 0.03, 0.0, d, 0.0, h));
    scene.add(SHELVING, p.bx(w / 2.0 - 0.03, w / 2.0, 0.0, d, 0.0, h));
    scene.add(SHELVING, p.bx(-w / 2.0, w / 2.0, 0.0, 0.02, 0.0, h));
    for i in 0..5 {
        let z = 0.05 + i as f64 * (h - 0.1) / 4.0;
        scene.add(
            SHELVING,
            p.bx(-w / 2.0, w / 2.0, 0.0, d, z - 0.02, z + 0.02),
        );
    }
}

pub(super) fn kitchen_run(scene: &mut Scene, p: &Place, run: f64, rng: &mut ChaCha8Rng) {
    let a0 = -run / 2.0;
    // Fridge at one end, then counter with a stove and a sink in it.
    scene.add(FRIDGE, p.bx(a0, a0 + 0.7, 0.0, 0.68, 0.0, 1.85));
    let c0 = a0 + 0.72;
    let c1 = run / 2.0;
    scene.add(COUNTER, p.bx(c0, c1, 0.0, 0.62, 0.0, 0.9));
    let len = c1 - c0;
    if len > 1.4 {
        let s = c0 + rng.random_range(0.05..(len - 1.35).max(0.06));
        scene.add(STOVE, p.bx(s, s + 0.6, 0.02, 0.62, 0.0, 0.93));
        let k = s + 0.7;
        scene.add(SINK, p.bx(k, k + 0.6, 0.1, 0.55, 0.86, 0.93));
    }
    scene.add(CABINET, p.bx(c0, c1, 0.0, 0.35, 1.45, 2.2));
}

pub(super) fn plant_and_lamp(scene: &mut Scene, f: &mut Furnisher, rng: &mut ChaCha8Rng) {
    if let Some(p) = f.against_wall(rng, 0.6, 0.6, false) {
        let c = p.at(0.0, 0.3);
        scene.add(
            PLANT,
            Shape::Cylinder {
                x: c[0],
                y: c[1],
                radius: 0.16,
                z0: 0.0,
                z1: 0.32,
            },
        );
        let hgt = rng.random_range(0.3..0.55);
        scene.add(
            PLANT,
            Shape::Ellipsoid {
                centre: [c[0], c[1], 0.32 + hgt],
                radii: [0.28, 0.28, hgt],
            },
        );
    }
    if rng.random_bool(0.7)
        && let Some(p) = f.against_wall(rng, 0.45, 0.45, false)
    {
        let c = p.at(0.0, 0.22);
        scene.add(
            LAMP,
            Shape::Cylinder {
                x: c[0],
                y: c[1],
                radius: 0.15,
                z0: 0.0,
                z1: 0.03,
            },
        );
        scene.add(
            LAMP,
            Shape::Cylinder {
                x: c[0],
                y: c[1],
                radius: 0.025,
                z0: 0.03,
                z1: 1.45,
            },
        );
        scene.add(
            LAMP,
            Shape::Cylinder {
                x: c[0],
                y: c[1],
                radius: 0.2,
                z0: 1.4,
                z1: 1.7,
            },
        );
    }
}

pub(super) fn pictures(scene: &mut Scene, f: &mut Furnisher, rng: &mut ChaCha8Rng, n: usize) {
    for _ in 0..n {
        let w = rng.random_range(0.4..0.9);
        let wall = 2 + rng.random_range(0..2);
        let rm = f.rm;
        let (lo, hi) = (rm.min[1], rm.max[1]);
        if hi - lo < w + 0.4 {
            continue;
        }
        let along = rng.random_range(lo + w / 2.0 + 0.2..hi - w / 2.0 - 0.2);
        let p = wall_place(rm, wall, along, 0.05);
        let z0 = rng.random_range(1.3..1.6);
        scene.add(
            PICTURE,
            p.bx(-w / 2.0, w / 2.0, 0.0, 0.03, z0, z0 + w * 0.75),
        );
    }
}
