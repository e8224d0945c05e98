//! Worlds as labelled primitives, and their voxelization into labelled
//! surface cells.
//!
//! A [`Scene`] is a list of [`Primitive`]s (axis-aligned boxes, vertical
//! cylinders, ellipsoids), each with a class id. [`voxelize`] turns it into a
//! [`VoxelWorld`]: the cells (integer indices in the grid frame, cell
//! `(i, j, k)` spans `[i r, (i+1) r)` etc. from `origin`) that lie on a
//! primitive's surface, with that primitive's class. Only surface shells are
//! kept, because the language map stores observed surfaces; where primitives
//! overlap the later one wins, so furniture added after the floor labels the
//! floor cells it stands on, and cells buried on all six sides are dropped.

use nalgebra::Vector3;
use rustc_hash::FxHashMap;

/// An axis-aligned box in world coordinates (metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: [f64; 3],
    pub max: [f64; 3],
}

impl Aabb {
    /// A box from its two corners (any order).
    pub fn new(a: [f64; 3], b: [f64; 3]) -> Self {
        Aabb {
            min: [a[0].min(b[0]), a[1].min(b[1]), a[2].min(b[2])],
            max: [a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2])],
        }
    }

    /// True when `p` lies inside or on the box.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|a| p[a] >= self.min[a] && p[a] <= self.max[a])
    }
}

/// A solid shape in world coordinates (metres, z up).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Axis-aligned box.
    Box(Aabb),
    /// Vertical cylinder: axis through `(x, y)`, from `z0` to `z1`.
    Cylinder {
        x: f64,
        y: f64,
        radius: f64,
        z0: f64,
        z1: f64,
    },
    /// Axis-aligned ellipsoid: centre and semi-axes.
    Ellipsoid { centre: [f64; 3], radii: [f64; 3] },
}

impl Shape {
    /// True when `p` lies inside the solid.
    pub fn contains(&self, p: [f64; 3]) -> bool {
        match *self {
            Shape::Box(b) => b.contains(p),
            Shape::Cylinder {
                x,
                y,
                radius,
                z0,
                z1,
            } => {
                p[2] >= z0
                    && p[2] <= z1
                    && (p[0] - x).powi(2) + (p[1] - y).powi(2) <= radius * radius
            }
            Shape::Ellipsoid { centre, radii } => {
                (0..3)
                    .map(|a| ((p[a] - centre[a]) / radii[a]).powi(2))
                    .sum::<f64>()
                    <= 1.0
            }
        }
    }

    /// Bounding box.
    pub fn bounds(&self) -> Aabb {
        match *self {
            Shape::Box(b) => b,
            Shape::Cylinder {
                x,
                y,
                radius,
                z0,
                z1,
            } => Aabb::new([x - radius, y - radius, z0], [x + radius, y + radius, z1]),
            Shape::Ellipsoid {
                centre: c,
                radii: r,
            } => Aabb::new(
                [c[0] - r[0], c[1] - r[1], c[2] - r[2]],
                [c[0] + r[0], c[1] + r[1], c[2] + r[2]],
            ),
        }
    }
}

/// A shape with a class id.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Primitive {
    pub shape: Shape,
    /// Class id (index into the scene's class names).
    pub label: u16,
}

/// A world before voxelization: class names and primitives, later ones
/// painted over earlier ones.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// Class names, id = index.
    pub classes: Vec<String>,
    pub primitives: Vec<Primitive>,
}

impl Scene {
    /// An empty scene with these class names.
    pub fn new(classes: &[&str]) -> Self {
        Scene {
            classes: classes.iter().map(|s| s.to_string()).collect(),
            primitives: Vec::new(),
        }
    }

    /// Adds a box with class `label`.
    pub fn add_box(&mut self, label: u16, a: [f64; 3], b: [f64; 3]) {
        self.primitives.push(Primitive {
            shape: Shape::Box(Aabb::new(a, b)),
            label,
        });
    }

    /// Adds any shape with class `label`.
    pub fn add(&mut self, label: u16, shape: Shape) {
        self.primitives.push(Primitive { shape, label });
    }

    /// Bounding box of all primitives (`None` for an empty scene).
    pub fn bounds(&self) -> Option<Aabb> {
        let mut it = self.primitives.iter().map(|p| p.shape.bounds());
        let first = it.next()?;
        Some(it.fold(first, |acc, b| {
            Aabb::new(
                [
                    acc.min[0].min(b.min[0]),
                    acc.min[1].min(b.min[1]),
                    acc.min[2].min(b.min[2]),
                ],
                [
                    acc.max[0].max(b.max[0]),
                    acc.max[1].max(b.max[1]),
                    acc.max[2].max(b.max[2]),
                ],
            )
        }))
    }
}

/// A voxelized world: labelled surface cells on a regular grid.
#[derive(Debug, Clone, PartialEq)]
pub struct VoxelWorld {
    /// Edge length of a cell, metres.
    pub resolution: f64,
    /// World coordinates of the grid frame's zero (corner of cell (0,0,0)).
    pub origin: Vector3<f64>,
    /// Occupied cells, sorted by (k, j, i).
    pub cells: Vec<[i32; 3]>,
    /// Class id of each cell.
    pub labels: Vec<u16>,
    /// Class names, id = index.
    pub classes: Vec<String>,
}

impl VoxelWorld {
    /// World coordinates of the centre of cell `c`.
    pub fn cell_centre(&self, c: [i32; 3]) -> Vector3<f64> {
        self.origin
            + Vector3::new(c[0] as f64 + 0.5, c[1] as f64 + 0.5, c[2] as f64 + 0.5)
                * self.resolution
    }

    /// The cell containing world point `p`.
    pub fn cell_of(&self, p: &Vector3<f64>) -> [i32; 3] {
        let q = (p - self.origin) / self.resolution;
        [q.x.floor() as i32, q.y.floor() as i32, q.z.floor() as i32]
    }

    /// Class of cell `c`, if occupied (binary search over the sorted cells).
    pub fn label_at(&self, c: [i32; 3]) -> Option<u16> {
        self.cells
            .binary_search_by(|x| (x[2], x[1], x[0]).cmp(&(c[2], c[1], c[0])))
            .ok()
            .map(|i| self.labels[i])
    }

    /// Number of cells of each class.
    pub fn class_histogram(&self) -> Vec<usize> {
        let mut h = vec![0; self.classes.len()];
        for &l in &self.labels {
            if let Some(n) = h.get_mut(l as usize) {
                *n += 1;
            }
        }
        h
    }
}

/// Voxelizes `scene` at `resolution` metres with the grid origin at
/// `origin`: the surface shell of every primitive (cells whose centre is
/// inside it and which have a face neighbour whose centre is outside it),
/// later primitives overwriting earlier ones, then cells enclosed on all six
/// sides removed. A primitive thinner than a cell still marks the cells that
/// contain its mid-plane, so thin pictures and rugs are not lost.
pub fn voxelize(scene: &Scene, resolution: f64, origin: Vector3<f64>) -> VoxelWorld {
    voxelize_onto(scene, resolution, origin, FxHashMap::default())
}

/// [`voxelize`] on top of cells made by other means (`base`: cell to
/// class), which the primitives paint over.
pub fn voxelize_onto(
    scene: &Scene,
    resolution: f64,
    origin: Vector3<f64>,
    base: FxHashMap<[i32; 3], u16>,
) -> VoxelWorld {
    let r = resolution;
    let o = origin;
    let mut map = base;
    for prim in &scene.primitives {
        let b = prim.shape.bounds();
        let mut lo = [0i32; 3];
        let mut hi = [0i32; 3];
        for a in 0..3 {
            let lo_f = ((b.min[a] - o[a]) / r - 0.5).ceil();
            let hi_f = ((b.max[a] - o[a]) / r - 0.5).floor();
            if hi_f < lo_f {
                // Thinner than a cell along this axis: keep the mid-plane cell.
                let mid = ((0.5 * (b.min[a] + b.max[a]) - o[a]) / r).floor() as i32;
                lo[a] = mid;
                hi[a] = mid;
            } else {
                lo[a] = lo_f as i32;
                hi[a] = hi_f as i32;
            }
        }
        let centre = |i: i32, j: i32, k: i32| {
            [
                o[0] + (i as f64 + 0.5) * r,
                o[1] + (j as f64 + 0.5) * r,
                o[2] + (k as f64 + 0.5) * r,
            ]
        };
        // Inside test on the clamped index box; thin axes count as inside.
        let inside = |i: i32, j: i32, k: i32| {
            if i < lo[0] || i > hi[0] || j < lo[1] || j > hi[1] || k < lo[2] || k > hi[2] {
                return false;
            }
            match prim.shape {
                Shape::Box(_) => true,
                _ => {
                    let mut p = centre(i, j, k);
                    for a in 0..3 {
                        if lo[a] == hi[a] {
                            p[a] = p[a].clamp(b.min[a], b.max[a]);
                        }
                    }
                    prim.shape.contains(p)
                }
            }
        };
        for k in lo[2]..=hi[2] {
            for j in lo[1]..=hi[1] {
                for i in lo[0]..=hi[0] {
                    if !inside(i, j, k) {
                        continue;
                    }
                    let shell = !(inside(i - 1, j, k)
                        && inside(i + 1, j, k)
                        && inside(i, j - 1, k)
                        && inside(i, j + 1, k)
                        && inside(i, j, k - 1)
                        && inside(i, j, k + 1));
                    if shell {
                        map.insert([i, j, k], prim.label);
                    }
                }
            }
        }
    }
    let occupied = |c: [i32; 3]| map.contains_key(&c);
    let mut cells: Vec<([i32; 3], u16)> = map
        .iter()
        .filter(|(c, _)| {
            let [i, j, k] = **c;
            !(occupied([i - 1, j, k])
                && occupied([i + 1, j, k])
                && occupied([i, j - 1, k])
                && occupied([i, j + 1, k])
                && occupied([i, j, k - 1])
                && occupied([i, j, k + 1]))
        })
        .map(|(c, l)| (*c, *l))
        .collect();
    cells.sort_unstable_by_key(|(c, _)| (c[2], c[1], c[0]));
    VoxelWorld {
        resolution,
        origin,
        cells: cells.iter().map(|(c, _)| *c).collect(),
        labels: cells.iter().map(|(_, l)| *l).collect(),
        classes: scene.classes.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_shell_has_the_expected_cell_count() {
        // A 1 m cube at 0.1 m: 10^3 cells, shell = 10^3 - 8^3 = 488.
        let mut s = Scene::new(&["a"]);
        s.add_box(0, [0.0, 0.0, 0.0], [1.0, 1.0, 1.0]);
        let w = voxelize(&s, 0.1, Vector3::zeros());
        assert_eq!(w.cells.len(), 488);
        assert_eq!(w.label_at([0, 0, 0]), Some(0));
        assert_eq!(w.label_at([5, 5, 5]), None);
        assert_eq!(w.cell_of(&Vector3::new(0.55, 0.05, 0.99)), [5, 0, 9]);
    }

    #[test]
    fn later_primitives_paint_over_earlier_ones_and_thin_ones_survive() {
        let mut s = Scene::new(&["floor", "rug"]);
        s.add_box(0, [0.0, 0.0, -0.1], [2.0, 2.0, 0.0]);
        // A 1 cm rug above the floor: thinner than a cell.
        s.add_box(1, [0.5, 0.5, 0.0], [1.0, 1.0, 0.01]);
        let w = voxelize(&s, 0.1, Vector3::zeros());
        assert_eq!(w.label_at([7, 7, 0]), Some(1));
        assert_eq!(w.label_at([7, 7, -1]), Some(0));
        assert_eq!(w.label_at([15, 15, -1]), Some(0));
        assert_eq!(w.class_histogram(), vec![400, 25]);
    }

    #[test]
    fn cylinder_and_ellipsoid_cells_lie_near_their_surface() {
        let mut s = Scene::new(&["pole", "ball"]);
        s.add(
            0,
            Shape::Cylinder {
                x: 0.0,
                y: 0.0,
                radius: 0.5,
                z0: 0.0,
                z1: 2.0,
            },
        );
        s.add(
            1,
            Shape::Ellipsoid {
                centre: [3.0, 0.0, 1.0],
                radii: [0.6, 0.6, 0.6],
            },
        );
        let w = voxelize(&s, 0.05, Vector3::new(-1.0, -1.0, -0.5));
        for (c, &l) in w.cells.iter().zip(&w.labels) {
            let p = w.cell_centre(*c);
            if l == 0 && p.z > 0.1 && p.z < 1.9 {
                let rad = (p.x * p.x + p.y * p.y).sqrt();
                assert!(rad > 0.5 - 0.1 && rad <= 0.5, "{rad}");
            }
            if l == 1 {
                let d = (p - Vector3::new(3.0, 0.0, 1.0)).norm();
                assert!(d > 0.6 - 0.1 && d <= 0.6, "{d}");
            }
        }
    }
}
