//! Camera paths and odometry.
//!
//! Indoor paths walk from room to room through doors and the hall,
//! turn in place at each room's viewpoint and sway their heading while
//! walking, at a fixed number of frames. Outdoor paths are a real driving
//! path (KITTI 00) moved into the world frame. Odometry is the ground-truth
//! relative motion composed with optional real drift (the relative motion
//! errors of a real estimate against its ground truth) and Gaussian noise.
//!
//! Poses are `world_from_camera` (OpenCV camera, world z up).

use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

use super::indoor::IndoorLayout;
use crate::geometry::Pose;

/// Parameters of an indoor camera path.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct IndoorPathConfig {
    /// Number of frames.
    pub frames: usize,
    /// Seed of the room order and turn amounts.
    pub seed: u64,
    /// Camera height above the floor, metres.
    pub height: f64,
    /// Translation per walking frame, metres.
    pub step: f64,
    /// Heading change per frame of an in-place turn, degrees.
    pub turn_rate_deg: f64,
    /// Amplitude of the heading sway while walking, degrees.
    pub sway_deg: f64,
}

impl Default for IndoorPathConfig {
    fn default() -> Self {
        // Step, turn rate and sway chosen so that the mean motion per frame
        // comes out near the paper's 0.13 m and 8 degrees (see tests).
        IndoorPathConfig {
            frames: 300,
            seed: 0,
            height: 1.5,
            step: 0.28,
            turn_rate_deg: 16.0,
            sway_deg: 10.0,
        }
    }
}

/// The camera pose at `position` (world, metres) looking along heading
/// `yaw` (radians from world +x towards +y), optical axis level.
pub fn level_camera(position: Vector3<f64>, yaw: f64) -> Pose {
    let z = Vector3::new(yaw.cos(), yaw.sin(), 0.0);
    let x = Vector3::new(yaw.sin(), -yaw.cos(), 0.0);
    let y = Vector3::new(0.0, 0.0, -1.0);
    let rot = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Pose::from_parts(
        Translation3::from(position),
        UnitQuaternion::from_rotation_matrix(&rot),
    )
}

/// An indoor path through the rooms of `layout`: start at a room's
/// viewpoint, look around, walk out through the door, along the hall (the
/// corridor, the aisle) by the shortest way, into the next room of the
/// layout's tour, and so on until `config.frames` poses exist.
pub fn indoor_path(layout: &IndoorLayout, config: &IndoorPathConfig) -> Vec<Pose> {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0xba7_0000_u64);
    // Visit rooms in the layout's tour order from a random start, wrapping around.
    let mut order: Vec<usize> = layout.tour.clone();
    let start = rng.random_range(0..order.len().max(1));
    order.rotate_left(start);
    let mut poses = Vec::with_capacity(config.frames);
    let mut walker = Walker {
        pos: [0.0, 0.0],
        yaw: 0.0,
        phase: rng.random_range(0.0..std::f64::consts::TAU),
        config,
        poses: &mut poses,
    };
    let Some(&first) = order.first() else {
        return Vec::new();
    };
    let r0 = &layout.rooms[first];
    walker.pos = r0.viewpoint;
    walker.yaw = rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
    let mut i = 0;
    while walker.poses.len() < config.frames {
        let room = &layout.rooms[order[i % order.len()]];
        let look = rng.random_range(150.0..300.0f64).to_radians()
            * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        walker.turn_by(look);
        let next = &layout.rooms[order[(i + 1) % order.len()]];
        let step_in = |rm: &super::indoor::Room| {
            [
                rm.door[0] + rm.inward[0] * 0.5,
                rm.door[1] + rm.inward[1] * 0.5,
            ]
        };
        let hall = hall_route(layout, room.hall_node, next.hall_node);
        let targets = [step_in(room), room.door].into_iter().chain(hall).chain([
            next.door,
            step_in(next),
            next.viewpoint,
        ]);
        for target in targets {
            walker.walk_to(target);
        }
        i += 1;
    }
    poses.truncate(config.frames);
    poses
}

/// The hall waypoints from node `from` to node `to` of `layout`: the
/// shortest way along hall edges, both ends included, with waypoints in
/// the middle of a straight run dropped (a walk does not stop at them).
fn hall_route(layout: &IndoorLayout, from: usize, to: usize) -> Vec<[f64; 2]> {
    let n = layout.hall.len();
    if from >= n || to >= n {
        return Vec::new();
    }
    let len = |a: usize, b: usize| {
        let (p, q) = (layout.hall[a], layout.hall[b]);
        (p[0] - q[0]).hypot(p[1] - q[1])
    };
    // Dijkstra on a graph of a few dozen nodes: quadratic is plenty.
    let mut dist = vec![f64::INFINITY; n];
    let mut prev = vec![usize::MAX; n];
    let mut done = vec![false; n];
    dist[from] = 0.0;
    while let Some(u) = (0..n)
        .filter(|&i| !done[i] && dist[i].is_finite())
        .min_by(|&a, &b| dist[a].total_cmp(&dist[b]))
    {
        done[u] = true;
        if u == to {
            break;
        }
        for e in &layout.hall_edges {
            let v = if e[0] == u {
                e[1]
            } else if e[1] == u {
                e[0]
            } else {
                continue;
            };
            let d = dist[u] + len(u, v);
            if d < dist[v] {
                dist[v] = d;
                prev[v] = u;
            }
        }
    }
    let mut nodes = vec![to];
    while let Some(&last) = nodes.last() {
        if last == from {
            break;
        }
        match prev.get(last) {
            Some(&p) if p != usize::MAX => nodes.push(p),
            // Not connected: go straight (the layouts connect every node).
            _ => {
                nodes.push(from);
                break;
            }
        }
    }
    nodes.reverse();
    let pts: Vec<[f64; 2]> = nodes.iter().map(|&i| layout.hall[i]).collect();
    let mut out: Vec<[f64; 2]> = Vec::with_capacity(pts.len());
    for (i, &p) in pts.iter().enumerate() {
        let straight = i > 0 && i + 1 < pts.len() && {
            let (a, c) = (pts[i - 1], pts[i + 1]);
            let (u, v) = ([p[0] - a[0], p[1] - a[1]], [c[0] - p[0], c[1] - p[1]]);
            (u[0] * v[1] - u[1] * v[0]).abs() < 1e-9 && u[0] * v[0] + u[1] * v[1] > 0.0
        };
        if !straight {
            out.push(p);
        }
    }
    out
}

struct Walker<'a> {
    pos: [f64; 2],
    yaw: f64,
    phase: f64,
    config: &'a IndoorPathConfig,
    poses: &'a mut Vec<Pose>,
}

impl Walker<'_> {
    fn emit(&mut self, yaw: f64) {
        if self.poses.len() < self.config.frames {
            let p = Vector3::new(self.pos[0], self.pos[1], self.config.height);
            self.poses.push(level_camera(p, yaw));
        }
    }

    fn turn_by(&mut self, angle: f64) {
        let rate = self.config.turn_rate_deg.to_radians().max(1e-3);
        let n = (angle.abs() / rate).ceil().max(1.0) as usize;
        for k in 1..=n {
            self.emit(self.yaw + angle * k as f64 / n as f64);
        }
        self.yaw += angle;
    }

    fn walk_to(&mut self, target: [f64; 2]) {
        let dx = target[0] - self.pos[0];
        let dy = target[1] - self.pos[1];
        let dist = dx.hypot(dy);
        if dist < 1e-6 {
            return;
        }
        let heading = dy.atan2(dx);
        let mut d = heading - self.yaw;
        d = (d + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        if d.abs() > 1e-6 {
            self.turn_by(d);
        }
        let n = (dist / self.config.step).ceil() as usize;
        let sway = self.config.sway_deg.to_radians();
        let start = self.pos;
        for k in 1..=n {
            let s = k as f64 / n as f64;
            self.pos = [start[0] + s * dx, start[1] + s * dy];
            self.phase += 0.3;
            // The sway fades in and out at segment ends so turns stay turns.
            let fade = (std::f64::consts::PI * s).sin();
            self.emit(self.yaw + sway * fade * self.phase.sin());
        }
        self.pos = target;
    }
}

/// The paper's odometry noise per unit of motion: 0.10 m per 0.13 m and
/// 6 degrees per 8 degrees.
pub const PAPER_NOISE_PER_MOTION: (f64, f64) = (0.10 / 0.13, 6.0 / 8.0);

/// Odometry noise per step (metres, degrees) in the paper's proportion to
/// the mean motion of `poses` (for paths whose steps are not the paper's).
pub fn paper_noise_for(poses: &[Pose]) -> (f64, f64) {
    let (t, r) = mean_motion(poses);
    (PAPER_NOISE_PER_MOTION.0 * t, PAPER_NOISE_PER_MOTION.1 * r)
}

/// Mean translation (metres) and rotation (degrees) per frame of a path.
pub fn mean_motion(poses: &[Pose]) -> (f64, f64) {
    if poses.len() < 2 {
        return (0.0, 0.0);
    }
    let mut t = 0.0;
    let mut r = 0.0;
    for w in poses.windows(2) {
        let d = w[0].inverse() * w[1];
        t += d.translation.vector.norm();
        r += d.rotation.angle().to_degrees();
    }
    let n = (poses.len() - 1) as f64;
    (t / n, r / n)
}

/// The rotation taking KITTI camera-0 axes (x right, y down, z forward) to
/// a z-up world whose x is the car's initial forward direction.
pub fn world_from_kitti() -> Pose {
    let rot = Rotation3::from_matrix_unchecked(Matrix3::new(
        0.0, 0.0, 1.0, //
        -1.0, 0.0, 0.0, //
        0.0, -1.0, 0.0,
    ));
    Pose::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_rotation_matrix(&rot),
    )
}

/// Odometry noise and drift model.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OdometryConfig {
    /// Seed of the Gaussian noise.
    pub seed: u64,
    /// Standard deviation of the translation noise per frame and axis of the
    /// ground plane (camera x and z), metres.
    pub sigma_t: f64,
    /// Standard deviation of the heading noise per frame (about camera y), degrees.
    pub sigma_r_deg: f64,
    /// Scale applied to the translation of the real drift errors (1 for the
    /// scale they were recorded at; smaller for slow indoor motion).
    pub drift_scale: f64,
    /// Noise on all six degrees of freedom (`sigma_t` on each axis,
    /// `sigma_r_deg` about each axis) instead of the ground plane and the
    /// heading: the 6-DoF block of Table I.
    #[serde(default)]
    pub all_axes: bool,
}

impl Default for OdometryConfig {
    fn default() -> Self {
        // The paper's noise: 0.10 m and 6 degrees per step.
        OdometryConfig {
            seed: 0,
            sigma_t: 0.10,
            sigma_r_deg: 6.0,
            drift_scale: 0.15,
            all_axes: false,
        }
    }
}

/// Relative motion errors of an estimate against ground truth,
/// `(gt_{i-1}^-1 gt_i)^-1 (est_{i-1}^-1 est_i)`, in the moving camera frame.
pub fn drift_errors(gt: &[Pose], estimate: &[Pose]) -> Vec<Pose> {
    gt.windows(2)
        .zip(estimate.windows(2))
        .map(|(g, e)| (g[0].inverse() * g[1]).inverse() * (e[0].inverse() * e[1]))
        .collect()
}

/// Noisy odometry poses for a ground-truth path: the first pose equals the
/// ground truth; every later one composes the true relative motion with the
/// next drift error (cycled, translation scaled by `drift_scale`) and
/// Gaussian noise in the camera's ground plane (or on all six degrees of
/// freedom, `all_axes`), so errors accumulate as real odometry's do. The
/// one definition of odometry noise: the benchmark, Table IV's streets,
/// the 6-DoF block and `omcl localize --odom-noise-m` all draw it here.
pub fn odometry(gt: &[Pose], drift: &[Pose], config: &OdometryConfig) -> Vec<Pose> {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed ^ 0x0d0_0e7e7);
    let nt = Normal::new(0.0, config.sigma_t.max(0.0)).ok();
    let nr = Normal::new(0.0, config.sigma_r_deg.max(0.0).to_radians()).ok();
    let mut out = Vec::with_capacity(gt.len());
    let Some(&first) = gt.first() else {
        return out;
    };
    out.push(first);
    for (i, w) in gt.windows(2).enumerate() {
        let mut rel = w[0].inverse() * w[1];
        if !drift.is_empty() {
            let mut e = drift[i % drift.len()];
            e.translation.vector *= config.drift_scale;
            rel *= e;
        }
        let mut draw = |n: &Option<Normal<f64>>| n.as_ref().map_or(0.0, |n| n.sample(&mut rng));
        let noise = if config.all_axes {
            let t = Translation3::new(draw(&nt), draw(&nt), draw(&nt));
            let r = Vector3::new(draw(&nr), draw(&nr), draw(&nr));
            Pose::from_parts(t, UnitQuaternion::from_scaled_axis(r))
        } else {
            let (tx, tz, ry) = (draw(&nt), draw(&nt), draw(&nr));
            Pose::from_parts(
                Translation3::new(tx, 0.0, tz),
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), ry),
            )
        };
        rel *= noise;
        let prev = *out.last().unwrap_or(&first);
        out.push(prev * rel);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::indoor::{IndoorConfig, WorldKind, generate};

    #[test]
    fn all_axes_noise_moves_every_degree_of_freedom_planar_noise_only_three() {
        let path: Vec<Pose> = (0..400)
            .map(|i| level_camera(Vector3::new(0.1 * i as f64, 0.0, 1.5), 0.0))
            .collect();
        let noise_of = |all_axes| {
            let cfg = OdometryConfig {
                seed: 9,
                all_axes,
                ..Default::default()
            };
            let odo = odometry(&path, &[], &cfg);
            // Each step's error, in the camera frame: (gt increment)^-1 * (odometry increment).
            let errs: Vec<Pose> = (1..path.len())
                .map(|i| {
                    (path[i - 1].inverse() * path[i]).inverse() * (odo[i - 1].inverse() * odo[i])
                })
                .collect();
            let std = |f: &dyn Fn(&Pose) -> f64| {
                (errs.iter().map(|e| f(e).powi(2)).sum::<f64>() / errs.len() as f64).sqrt()
            };
            let t = |k: usize| std(&|e: &Pose| e.translation.vector[k]);
            let r = |k: usize| std(&|e: &Pose| e.rotation.scaled_axis()[k].to_degrees());
            ([t(0), t(1), t(2)], [r(0), r(1), r(2)])
        };
        let (t, r) = noise_of(true);
        for k in 0..3 {
            assert!(
                (0.085..0.115).contains(&t[k]),
                "all axes: translation {t:?}"
            );
            assert!((5.1..6.9).contains(&r[k]), "all axes: rotation {r:?}");
        }
        // Planar: camera x and z, and the heading about camera y only.
        let (t, r) = noise_of(false);
        assert!(t[1] < 1e-9 && r[0] < 1e-6 && r[2] < 1e-6, "{t:?} {r:?}");
        assert!((0.085..0.115).contains(&t[0]) && (0.085..0.115).contains(&t[2]));
        assert!((5.1..6.9).contains(&r[1]), "{r:?}");
    }

    #[test]
    fn level_camera_looks_along_its_heading() {
        let p = level_camera(Vector3::new(1.0, 2.0, 1.5), std::f64::consts::FRAC_PI_2);
        let fwd = p.rotation * Vector3::z();
        let down = p.rotation * Vector3::y();
        assert!((fwd - Vector3::y()).norm() < 1e-12);
        assert!((down + Vector3::z()).norm() < 1e-12);
        // Right-handed: x = y cross z.
        let right = p.rotation * Vector3::x();
        assert!((right - Vector3::x()).norm() < 1e-12);
    }

    #[test]
    fn indoor_path_has_paper_like_motion_and_visits_rooms() {
        let w = generate(&IndoorConfig::default());
        let path = indoor_path(&w.layout, &IndoorPathConfig::default());
        assert_eq!(path.len(), 300);
        let (t, r) = mean_motion(&path);
        assert!((0.10..0.16).contains(&t), "mean step {t} m");
        assert!((6.0..10.0).contains(&r), "mean turn {r} deg");
        let mut visited = 0;
        for rm in &w.layout.rooms {
            if path.iter().any(|p| {
                let q = p.translation.vector;
                q.x > rm.min[0] && q.x < rm.max[0] && q.y > rm.min[1] && q.y < rm.max[1]
            }) {
                visited += 1;
            }
        }
        assert!(visited >= 3, "visited {visited} rooms");
        assert!(
            path.iter()
                .all(|p| (p.translation.vector.z - 1.5).abs() < 1e-12)
        );
    }

    /// In every kind of world a long path stays clear of every surface
    /// (nothing within 0.15 m horizontally from knee to head height),
    /// turns at the viewpoint of most rooms, and moves as the paper's do.
    #[test]
    fn paths_in_every_kind_of_world_stay_free_and_reach_most_rooms() {
        for kind in WorldKind::ALL {
            for seed in [0, 1] {
                let w = generate(&IndoorConfig::of_kind(kind, seed));
                let rooms = &w.layout.rooms;
                let path = indoor_path(
                    &w.layout,
                    &IndoorPathConfig {
                        frames: 60 * rooms.len(),
                        seed,
                        ..Default::default()
                    },
                );
                let v = &w.voxels;
                let cells = (0.15 / v.resolution).round() as i32;
                for (i, pose) in path.iter().enumerate() {
                    let o = pose.translation.vector;
                    for z in [0.5, 1.0, 1.5, 1.9] {
                        let c = v.cell_of(&Vector3::new(o.x, o.y, z));
                        for di in -cells..=cells {
                            for dj in -cells..=cells {
                                let hit = v.label_at([c[0] + di, c[1] + dj, c[2]]);
                                assert!(
                                    hit.is_none(),
                                    "{kind} seed {seed} frame {i} at ({:.2}, {:.2}, {z}): {:?}",
                                    o.x,
                                    o.y,
                                    hit.map(|l| &v.classes[l as usize])
                                );
                            }
                        }
                    }
                }
                let reached = rooms
                    .iter()
                    .filter(|rm| {
                        path.iter().any(|p| {
                            let q = p.translation.vector;
                            (q.x - rm.viewpoint[0]).hypot(q.y - rm.viewpoint[1]) < 1e-6
                        })
                    })
                    .count();
                assert!(
                    5 * reached >= 4 * rooms.len(),
                    "{kind} seed {seed}: {reached} of {} viewpoints",
                    rooms.len()
                );
                let (t, r) = mean_motion(&path[..150]);
                assert!((0.10..0.17).contains(&t), "{kind} {seed}: {t} m a frame");
                assert!((6.0..11.0).contains(&r), "{kind} {seed}: {r} deg a frame");
            }
        }
    }

    #[test]
    fn odometry_without_noise_is_ground_truth_and_noise_accumulates() {
        let w = generate(&IndoorConfig::default());
        let path = indoor_path(
            &w.layout,
            &IndoorPathConfig {
                frames: 100,
                ..Default::default()
            },
        );
        let exact = odometry(
            &path,
            &[],
            &OdometryConfig {
                sigma_t: 0.0,
                sigma_r_deg: 0.0,
                ..Default::default()
            },
        );
        for (a, b) in exact.iter().zip(&path) {
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-9);
        }
        let noisy = odometry(&path, &[], &OdometryConfig::default());
        // Per-step relative errors have the configured spread.
        let errs = drift_errors(&path, &noisy);
        let n = errs.len() as f64;
        let sx = (errs
            .iter()
            .map(|e| e.translation.vector.x.powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        assert!((0.07..0.13).contains(&sx), "{sx}");
        let again = odometry(&path, &[], &OdometryConfig::default());
        assert_eq!(noisy, again);
    }

    #[test]
    fn kitti_axes_map_forward_to_world_x_and_down_to_minus_z() {
        let w = world_from_kitti();
        assert!((w.rotation * Vector3::z() - Vector3::x()).norm() < 1e-12);
        assert!((w.rotation * Vector3::y() + Vector3::z()).norm() < 1e-12);
        assert!((w.rotation * Vector3::x() + Vector3::y()).norm() < 1e-12);
    }
}
