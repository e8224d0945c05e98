//! The filter on known scenes: procedural rooms whose labels get random
//! unit features; "observed" features are rendered from the true pose.

use std::sync::Arc;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use super::particles::sort_spatially;
use super::*;
use crate::geometry::{Intrinsics, Pose, camera_ray, level_camera};
use crate::map::{FeatureDb, GridSpec, LanguageMap};
use crate::raycast::{RayCaster, ReferenceCaster};
use crate::scene::{self, RoomsConfig, Scene};

const DIM: usize = 32;

struct World {
    scene: Scene,
    map: LanguageMap,
    caster: Arc<dyn RayCaster>,
}

fn world() -> World {
    let scene = scene::rooms(&RoomsConfig::default());
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let labels = scene::FURNITURE_BASE + scene::FURNITURE_KINDS;
    let rows: Vec<f32> = (0..labels as usize * DIM)
        .map(|_| rng.sample::<f32, _>(StandardNormal))
        .collect();
    let db = FeatureDb::from_rows(DIM, 0.02, rows).expect("random rows");
    let grid = GridSpec {
        resolution: scene.resolution,
        origin: Vector3::zeros(),
    };
    let map = LanguageMap::from_cells(
        grid,
        db,
        "test",
        scene
            .cells
            .iter()
            .copied()
            .zip(scene.labels.iter().copied()),
    )
    .expect("map");
    let caster = SensorModel::embree_caster(scene.resolution as f32, &map.cells()).expect("embree");
    World {
        scene,
        map,
        caster: Arc::new(caster),
    }
}

fn intrinsics() -> Intrinsics {
    Intrinsics::from_hfov(96, 72, 90.0)
}

/// Features seen from `pose`: the hit voxel's row plus Gaussian noise of
/// `noise` per unit vector (zero for a miss).
fn render(w: &World, pose: &Pose, noise: f32, rng: &mut ChaCha8Rng) -> crate::frame::DenseFeatures {
    let k = intrinsics();
    let rays: Vec<_> = (0..k.height)
        .flat_map(|v| (0..k.width).map(move |u| (u, v)))
        .map(|(u, v)| camera_ray(&k, pose, &w.map.grid().origin, u, v))
        .collect();
    let hits = w.caster.cast_vec(&rays);
    let mut data = Vec::with_capacity(rays.len() * DIM);
    let scale = noise / (DIM as f32).sqrt();
    for h in hits {
        match w.map.rows().get(h.leaf as usize) {
            Some(&r) => data.extend(
                w.map
                    .db()
                    .row(r as usize)
                    .iter()
                    .map(|x| x + scale * rng.sample::<f32, _>(StandardNormal)),
            ),
            None => data.extend(std::iter::repeat_n(0.0, DIM)),
        }
    }
    crate::frame::DenseFeatures {
        width: k.width,
        height: k.height,
        dim: DIM,
        data,
    }
}

fn start_pose(w: &World) -> Pose {
    let [x, y] = w.scene.free_spots[0];
    level_camera(Vector3::new(x, y, 1.5), 0.4)
}

/// The start pose of `w`, `rays` pixels sampled from its rendered view
/// (feature noise 0.5) and their similarity table.
fn sampled_view(
    w: &World,
    rays: usize,
    rng: &mut ChaCha8Rng,
) -> (Pose, Vec<(u32, u32)>, SimilarityTable) {
    let truth = start_pose(w);
    let frame = render(w, &truth, 0.5, rng);
    let params = SamplingParams {
        rays,
        ..Default::default()
    };
    let pixels = sampling::sample_pixels(&frame, w.map.db(), &params, rng).unwrap();
    let table = SimilarityTable::new(&frame, &pixels, w.map.db(), false).unwrap();
    (truth, pixels, table)
}

#[test]
fn the_true_pose_scores_highest() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let (truth, pixels, table) = sampled_view(&w, 512, &mut rng);
    let mut sensor = SensorModel::new(
        w.caster.clone(),
        w.map.rows().into(),
        w.map.grid().origin,
        intrinsics(),
        SensorParams::default(),
    );
    let shift = |dx: f64, dy: f64, dyaw: f64| {
        let t = truth.translation.vector + Vector3::new(dx, dy, 0.0);
        Particle::new(level_camera(t, 0.4 + dyaw), 1.0)
    };
    let ps = vec![
        shift(0.0, 0.0, 0.0),
        shift(0.3, 0.0, 0.0),
        shift(0.0, -0.3, 0.0),
        shift(0.1, 0.1, 0.0),
        shift(0.0, 0.0, 0.15),
        shift(0.0, 0.0, -0.3),
        shift(1.0, 0.5, 1.0),
    ];
    let l = sensor.likelihoods(&ps, &pixels, &table).to_vec();
    // Noise 0.5 over the unit row: the expected cosine at the truth is
    // about 1 / sqrt(1.25) = 0.89.
    assert!(l[0] > 0.8, "{l:?}");
    for (i, li) in l.iter().enumerate().skip(1) {
        assert!(l[0] > li + 0.01, "particle {i}: {li} vs truth {}", l[0]);
    }
}

/// `n` level particles around `truth`: every third far off (0.8 m and rad),
/// the others gathered (0.05).
fn near_and_far(truth: &Pose, n: usize, rng: &mut ChaCha8Rng) -> Vec<Particle> {
    (0..n)
        .map(|i| {
            let s = if i % 3 == 0 { 0.8 } else { 0.05 };
            let mut g = || rng.sample::<f64, _>(StandardNormal) * s;
            let t = truth.translation.vector + Vector3::new(g(), g(), 0.0);
            Particle::new(level_camera(t, 0.4 + g()), 1.0)
        })
        .collect()
}

#[test]
fn early_rejection_stops_only_particles_far_below_the_best() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let (truth, pixels, table) = sampled_view(&w, 400, &mut rng);
    let ps = near_and_far(&truth, 41, &mut rng);
    let model = |early_reject, order| {
        SensorModel::new(
            w.caster.clone(),
            w.map.rows().into(),
            w.map.grid().origin,
            intrinsics(),
            SensorParams {
                early_reject,
                ..Default::default()
            },
        )
        .with_ray_order(order)
    };
    let e = EarlyReject {
        every: 4,
        ratio: 0.85,
    };
    for order in [RayOrder::ParticleMajor, RayOrder::PixelMajor] {
        let full = model(None, order)
            .likelihoods(&ps, &pixels, &table)
            .to_vec();
        // Ratio 0: nobody is stopped; the sums differ from one pass only
        // in their order.
        let all = EarlyReject { ratio: 0.0, ..e };
        let two = model(Some(all), order)
            .likelihoods(&ps, &pixels, &table)
            .to_vec();
        for (a, b) in full.iter().zip(&two) {
            assert!((a - b).abs() < 1e-5, "{a} vs {b}");
        }
        // The first pass by hand: every 4th pixel.
        let first: Vec<(u32, u32)> = pixels.iter().copied().step_by(4).collect();
        let cols: Vec<usize> = (0..pixels.len()).step_by(4).collect();
        let l = model(Some(e), order)
            .likelihoods(&ps, &pixels, &table)
            .to_vec();
        let first_means: Vec<f32> = {
            let sub = table.columns(&cols);
            model(None, order).likelihoods(&ps, &first, &sub).to_vec()
        };
        let best = first_means.iter().copied().fold(f32::MIN, f32::max);
        let (mut kept, mut stopped) = (0, 0);
        for i in 0..ps.len() {
            if first_means[i] >= 0.85 * best {
                // Kept: its full likelihood.
                assert!(
                    (l[i] - full[i]).abs() < 1e-5,
                    "{i}: {} vs {}",
                    l[i],
                    full[i]
                );
                kept += 1;
            } else {
                // Stopped: its first-pass mean, far below the best's.
                assert!((l[i] - first_means[i]).abs() < 1e-5, "{i}");
                assert!(full[i] < 0.95 * full.iter().copied().fold(f32::MIN, f32::max));
                stopped += 1;
            }
        }
        assert!(kept > 0 && stopped > 5, "kept {kept}, stopped {stopped}");
    }
}

#[test]
fn every_ray_order_gives_the_same_likelihoods_to_the_bit() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let (truth, pixels, table) = sampled_view(&w, 300, &mut rng);
    // 37 particles: two full groups of RAY_GROUP and a short one, some
    // gathered near the truth and some far off.
    let ps = near_and_far(&truth, 37, &mut rng);
    let model = |order| {
        SensorModel::new(
            w.caster.clone(),
            w.map.rows().into(),
            w.map.grid().origin,
            intrinsics(),
            SensorParams::default(),
        )
        .with_ray_order(order)
    };
    let mut by_particle = model(RayOrder::ParticleMajor);
    let mut by_pixel = model(RayOrder::PixelMajor);
    let a = by_particle.likelihoods(&ps, &pixels, &table).to_vec();
    let b = by_pixel.likelihoods(&ps, &pixels, &table).to_vec();
    assert!(!by_particle.last_pixel_major() && by_pixel.last_pixel_major());
    assert_eq!(a.len(), 37);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&a), bits(&b));
    // Not all alike: the far particles score lower than the near ones.
    assert!(a[1] > a[0] + 0.05, "{a:?}");
    // Single rays through the reference caster agree with the grouped cast.
    let reference = SensorModel::new(
        Arc::new(ReferenceCaster::new(
            w.map.grid().resolution as f32,
            &w.map.cells(),
        )),
        w.map.rows().into(),
        w.map.grid().origin,
        intrinsics(),
        SensorParams::default(),
    )
    .with_ray_order(RayOrder::PixelMajor)
    .likelihoods(&ps, &pixels, &table)
    .to_vec();
    // (Rays through a voxel edge may pick either voxel: a few of 300.)
    for (x, y) in a.iter().zip(&reference) {
        assert!((x - y).abs() < 0.01, "{a:?} vs {reference:?}");
    }
}

/// The planar caster, with or without its fan path, counting the batches
/// cast each way.
struct Counted {
    inner: crate::raycast::PlanarCaster,
    fans: bool,
    calls: [std::sync::atomic::AtomicUsize; 2],
}

impl Counted {
    fn new(inner: crate::raycast::PlanarCaster, fans: bool) -> Arc<Self> {
        Arc::new(Counted {
            inner,
            fans,
            calls: Default::default(),
        })
    }
    /// Batches cast as fans and as rays.
    fn calls(&self) -> [usize; 2] {
        self.calls
            .each_ref()
            .map(|c| c.load(std::sync::atomic::Ordering::Relaxed))
    }
}

impl RayCaster for Counted {
    fn cast_serial(&self, rays: &[crate::geometry::Ray], hits: &mut [crate::raycast::Hit]) {
        self.calls[1].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.inner.cast_serial(rays, hits)
    }
    fn cast_fans(
        &self,
        origin: [f32; 3],
        fans: &[crate::raycast::Fan],
        slopes: &[f32],
        t_max: &[f32],
        hits: &mut [crate::raycast::Hit],
    ) -> bool {
        self.calls[0].fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        self.fans && self.inner.cast_fans(origin, fans, slopes, t_max, hits)
    }
    fn wants_column_order(&self) -> bool {
        true
    }
    fn len(&self) -> usize {
        self.inner.len()
    }
}

/// The rooms as a floor plan: one column per occupied (i, j) with the
/// vertical extent of its voxels, the leaf of its lowest voxel above the
/// floor layer; floor at the layer above the lowest, ceiling at the top.
fn rooms_plan(w: &World) -> (crate::raycast::PlanarCaster, Vec<u32>) {
    let r = w.map.grid().resolution as f32;
    let cells = w.map.cells();
    let z_lo = cells.iter().map(|c| c[2]).min().unwrap();
    let mut columns: std::collections::BTreeMap<(i32, i32), (usize, i32, i32)> = Default::default();
    for (k, c) in cells.iter().enumerate().filter(|(_, c)| c[2] > z_lo) {
        let e = columns.entry((c[0], c[1])).or_insert((k, c[2], c[2]));
        e.1 = e.1.min(c[2]);
        e.2 = e.2.max(c[2]);
    }
    let plan: Vec<_> = columns.keys().map(|&(i, j)| [i, j, 0]).collect();
    let extents: Vec<[f32; 2]> = columns
        .values()
        .map(|&(_, b, t)| [b as f32 * r, (t + 1) as f32 * r])
        .collect();
    let rows: Vec<u32> = columns.values().map(|&(k, _, _)| w.map.rows()[k]).collect();
    let top = cells.iter().map(|c| c[2]).max().unwrap() as f32 * r;
    let caster = crate::raycast::PlanarCaster::new(r, &plan).with_heights(
        &extents,
        [(z_lo + 1) as f32 * r, top],
        [crate::raycast::Hit::MISS; 2],
    );
    (caster, rows)
}

/// On a floor plan the sensor hands a level camera's rays to the planar
/// caster as fans (one walk an image column, no `Ray` made); the
/// likelihoods equal those of the same caster fed `Ray`s. Tilted cameras
/// take the ray path.
#[test]
fn fans_score_as_rays_do_on_a_floor_plan() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    let (truth, pixels, table) = sampled_view(&w, 300, &mut rng);
    let (plan, rows) = rooms_plan(&w);
    let model = |caster: Arc<dyn RayCaster>, max_range: f32| {
        SensorModel::new(
            caster,
            rows.clone().into(),
            w.map.grid().origin,
            intrinsics(),
            SensorParams {
                max_range,
                ..Default::default()
            },
        )
    };
    let level = near_and_far(&truth, 37, &mut rng);
    let tilt = UnitQuaternion::from_euler_angles(0.0, 0.0, 0.2);
    let tilted: Vec<Particle> = level
        .iter()
        .map(|p| {
            let pose = Pose::from_parts(p.pose.translation, p.pose.rotation * tilt);
            Particle::new(pose, 1.0)
        })
        .collect();
    for max_range in [f32::INFINITY, 2.0] {
        for (ps, is_level) in [(&level, true), (&tilted, false)] {
            let (with, without) = (
                Counted::new(plan.clone(), true),
                Counted::new(plan.clone(), false),
            );
            let fans = model(with.clone(), max_range)
                .likelihoods(ps, &pixels, &table)
                .to_vec();
            let rays = model(without.clone(), max_range)
                .likelihoods(ps, &pixels, &table)
                .to_vec();
            // Level: every particle cast as fans (37 particles, 3 groups
            // of RAY_GROUP), no ray made; tilted: no fan offered.
            if is_level {
                assert_eq!(with.calls(), [37, 0]);
                assert_eq!(without.calls(), [3, 3]);
            } else {
                assert_eq!(with.calls(), [0, 3]);
            }
            // (A ray through a column's corner may pick either column.)
            for (a, b) in fans.iter().zip(&rays) {
                assert!((a - b).abs() < 0.004, "{max_range}: {fans:?} vs {rays:?}");
            }
            // Not all alike: the particles see different columns.
            let (lo, hi) = fans
                .iter()
                .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &x| {
                    (a.min(x), b.max(x))
                });
            assert!(hi > lo + 0.05, "{fans:?}");
        }
    }
}

#[test]
fn pixel_major_is_chosen_for_gathered_particles_only() {
    let k = intrinsics();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let dirs: Vec<Vector3<f32>> = {
        let mut px: Vec<(u32, u32)> = (0..256)
            .map(|_| (rng.random_range(0..k.width), rng.random_range(0..k.height)))
            .collect();
        px.sort_unstable_by_key(|&(u, v)| (v / 8, u / 8));
        px.iter()
            .map(|&(u, v)| k.pixel_dir(u, v).cast::<f32>())
            .collect()
    };
    let cloud = |sxy: f64, syaw: f64, rng: &mut ChaCha8Rng| -> Vec<Particle> {
        let mut ps: Vec<Particle> = (0..512)
            .map(|_| {
                let mut g = || rng.sample::<f64, _>(StandardNormal);
                let t = Vector3::new(g() * sxy, g() * sxy, 1.5);
                Particle::new(level_camera(t, g() * syaw), 1.0)
            })
            .collect();
        sort_spatially(&mut ps, 0.05);
        ps
    };
    let gathered = cloud(0.02, 1f64.to_radians(), &mut rng);
    let spread = cloud(1.0, 60f64.to_radians(), &mut rng);
    assert!(pixel_major_pays(&gathered, &dirs, 8));
    assert!(!pixel_major_pays(&spread, &dirs, 8));
    // Too few particles or pixels for one packet: particle-major.
    assert!(!pixel_major_pays(&gathered[..7], &dirs, 8));
    assert!(!pixel_major_pays(&gathered, &dirs[..7], 8));
}

#[test]
fn packet_order_is_a_permutation_into_compact_runs() {
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    // 1000 particles (not a power of two): 0.1 m and 6 degrees of spread.
    let ps: Vec<Particle> = (0..1000)
        .map(|_| {
            let mut g = || rng.sample::<f64, _>(StandardNormal);
            let t = Vector3::new(g() * 0.1, g() * 0.1, 1.5);
            Particle::new(level_camera(t, g() * 6f64.to_radians()), 1.0)
        })
        .collect();
    let order = packet_order(&ps, 8);
    let mut seen = order.clone();
    seen.sort_unstable();
    assert_eq!(seen, (0..1000).collect::<Vec<u32>>());
    // Runs of 8: their widest pose difference (position plus the optical
    // axes' angle at FOOTPRINT_DEPTH) against the caller's order, which is
    // random here.
    let width = |ps: &[Particle]| -> f64 {
        let runs: Vec<f64> = ps
            .chunks_exact(8)
            .map(|run| {
                let p0 = &run[0].pose;
                run.iter()
                    .map(|p| {
                        (p.pose.translation.vector - p0.translation.vector).norm()
                            + FOOTPRINT_DEPTH as f64 * p0.rotation.angle_to(&p.pose.rotation)
                    })
                    .fold(0.0, f64::max)
            })
            .collect();
        runs.iter().sum::<f64>() / runs.len() as f64
    };
    let ordered: Vec<Particle> = order.iter().map(|&i| ps[i as usize]).collect();
    let (before, after) = (width(&ps), width(&ordered));
    assert!(after < 0.3 * before, "{after} vs {before}");
    // Narrower than the filter's Morton order too.
    let mut morton = ps.clone();
    sort_spatially(&mut morton, 0.05);
    assert!(
        after < 0.9 * width(&morton),
        "{after} vs {}",
        width(&morton)
    );
}

/// A 60-frame path in the first room (0.13 m and 8 degrees a frame) and its
/// odometry with 0.10 m / 6 degree noise.
fn path(w: &World, rng: &mut ChaCha8Rng) -> (Vec<Pose>, Vec<Pose>) {
    let [x, y] = w.scene.free_spots[0];
    let r = 0.13 / 8f64.to_radians();
    let gt: Vec<Pose> = (0..60)
        .map(|i| {
            let a = i as f64 * 8f64.to_radians();
            let p = Vector3::new(x + r * a.sin() - 0.2, y - r * a.cos() + r - 0.3, 1.5);
            level_camera(p, a)
        })
        .collect();
    let odom = gt
        .windows(2)
        .map(|g| {
            let inc = g[0].inverse() * g[1];
            // Noise in the camera frame: x right and z forward are
            // horizontal, yaw is about camera -y.
            let mut n = || rng.sample::<f64, _>(StandardNormal);
            let t = Vector3::new(n() * 0.1, 0.0, n() * 0.1);
            let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), n() * 6f64.to_radians());
            inc * Pose::from_parts(Translation3::from(t), q)
        })
        .collect();
    (gt, odom)
}

fn run(w: &World, config: FilterConfig, n: usize, seed: u64) -> (Vec<f64>, Vec<StepReport>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (gt, odom) = path(w, &mut rng);
    let init = local_init(&gt[0], n, 0.3, 17f64.to_radians(), &mut rng);
    let mut f = Filter::new(&w.map, w.caster.clone(), intrinsics(), config, init).unwrap();
    let mut errs = Vec::new();
    let mut reports = Vec::new();
    for (g, inc) in gt[1..].iter().zip(&odom) {
        let frame = render(w, g, 0.5, &mut rng);
        let rep = f.step(inc, &frame).unwrap();
        errs.push((rep.estimate.translation.vector - g.translation.vector).norm());
        reports.push(rep);
    }
    (errs, reports)
}

fn rmse(e: &[f64]) -> f64 {
    (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt()
}

#[test]
fn early_rejection_tracks_as_well_as_the_full_filter() {
    let w = world();
    let config = |early_reject| FilterConfig {
        sampling: SamplingParams {
            rays: 256,
            ..Default::default()
        },
        sensor: SensorParams {
            early_reject,
            ..Default::default()
        },
        seed: 3,
        ..Default::default()
    };
    let (full, _) = run(&w, config(None), 256, 3);
    let (two, _) = run(&w, config(Some(EarlyReject::default())), 256, 3);
    let (full, two) = (rmse(&full[10..]), rmse(&two[10..]));
    println!("APE RMSE after 10 frames: full {full:.3} m, two-pass {two:.3} m");
    assert!(two < 0.15 && two < 1.25 * full + 0.01, "{two} vs {full}");
}

#[test]
fn converges_from_a_local_initialization() {
    let w = world();
    let config = FilterConfig {
        sampling: SamplingParams {
            rays: 256,
            ..Default::default()
        },
        seed: 3,
        ..Default::default()
    };
    let (errs, reports) = run(&w, config, 256, 3);
    let tail = rmse(&errs[10..]);
    println!("APE RMSE after 10 frames: {tail:.3} m; errors {errs:.2?}");
    assert!(tail < 0.15, "APE RMSE {tail}");
    assert!(
        reports
            .iter()
            .all(|r| r.n_particles == 256 && r.n_rays > 80)
    );
    // Same seed, same run.
    let (again, _) = run(&w, config, 256, 3);
    assert_eq!(errs, again);
}

/// An expanded first layer (four copies of each particle, each with its
/// own motion noise, weighed on every fourth pixel) tracks as the plain
/// filter does and hands the next step the filter's own count.
#[test]
fn an_expanded_first_layer_tracks_and_keeps_the_count() {
    let w = world();
    let config = |expand| FilterConfig {
        sampling: SamplingParams {
            rays: 256,
            ..Default::default()
        },
        anneal: Some(Anneal {
            expand,
            ..Default::default()
        }),
        seed: 3,
        ..Default::default()
    };
    let (plain, _) = run(&w, config(1), 256, 3);
    let (errs, reports) = run(&w, config(4), 256, 3);
    let (plain, tail) = (rmse(&plain[10..]), rmse(&errs[10..]));
    println!("APE RMSE after 10 frames: two layers {plain:.3} m, expanded x4 {tail:.3} m");
    assert!(
        tail < 0.15 && tail < 1.25 * plain + 0.01,
        "{tail} vs {plain}"
    );
    assert!(reports.iter().all(|r| r.n_particles == 256));
    // One layer has nothing to expand into: refused by name.
    let one = Anneal {
        layers: 1,
        expand: 4,
        ..Default::default()
    };
    assert!(one.validate().unwrap_err().contains("anneal.expand"));
    for expand in [0, super::anneal::MAX_EXPAND + 1, u32::MAX] {
        let bad = Anneal {
            expand,
            ..Default::default()
        };
        assert!(bad.validate().unwrap_err().contains("anneal.expand"));
    }
}

/// A filter whose sampling leaves the map's strata off
/// (`SamplingParams::map_strata`, the floor plan's point-cloud filter)
/// steps exactly as one on a map that marks none, and one that keeps them
/// on draws other pixels, so another estimate.
#[test]
fn map_strata_off_ignores_the_rows_the_map_marks() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let (gt, odom) = path(&w, &mut rng);
    let init = local_init(&gt[0], 128, 0.3, 17f64.to_radians(), &mut rng);
    let frames: Vec<_> = gt[1..6]
        .iter()
        .map(|g| render(&w, g, 0.5, &mut rng))
        .collect();
    // Half the rows marked: the clustering then leaves the rest out.
    let mask: Vec<bool> = (0..w.map.db().len()).map(|r| r % 2 == 0).collect();
    let estimates = |map_strata: bool, strata: Option<Vec<bool>>| {
        let mut config = FilterConfig::default();
        config.sampling.rays = 256;
        config.sampling.map_strata = map_strata;
        let mut f = Filter::new(&w.map, w.caster.clone(), intrinsics(), config, init.clone())
            .unwrap()
            .with_strata(strata);
        frames
            .iter()
            .zip(&odom)
            .map(|(frame, inc)| f.step(inc, frame).unwrap().estimate)
            .collect::<Vec<_>>()
    };
    let none = estimates(true, None);
    assert_eq!(estimates(false, Some(mask.clone())), none);
    assert_ne!(estimates(true, Some(mask)), none);
}

/// Every k-th pixel's table is those pixels' own table.
#[test]
fn every_kth_pixels_table_is_their_own() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let frame = render(&w, &start_pose(&w), 0.3, &mut rng);
    let pixels: Vec<(u32, u32)> = (0..7).map(|i| (10 + 11 * i, 5 + 9 * i)).collect();
    let k = w.map.db().len();
    for contrast in [false, true] {
        let all = SimilarityTable::new(&frame, &pixels, w.map.db(), contrast).unwrap();
        for step in [1, 3] {
            let some: Vec<(u32, u32)> = pixels.iter().step_by(step).copied().collect();
            let direct = SimilarityTable::new(&frame, &some, w.map.db(), contrast).unwrap();
            let every = all.every(step);
            assert_eq!(every.pixels(), some.len());
            for j in 0..some.len() {
                for r in 0..k {
                    let (a, b) = (every.get(j, r), direct.get(j, r));
                    assert!((a - b).abs() < 1e-6, "{step} {j} {r}: {a} {b}");
                }
            }
        }
    }
}

#[test]
fn kld_shrinks_the_set_once_converged_and_recovery_injects_when_lost() {
    let w = world();
    let config = FilterConfig {
        sampling: SamplingParams {
            rays: 256,
            ..Default::default()
        },
        kld: Some(kld::KldParams {
            min_particles: 64,
            max_particles: 512,
            ..Default::default()
        }),
        // The scenario was tuned with the paper's plain cosines; KLD, not
        // the sensor, is under test here.
        sensor: SensorParams {
            contrast: false,
            ..Default::default()
        },
        seed: 4,
        ..Default::default()
    };
    let (errs, reports) = run(&w, config, 512, 4);
    assert!(rmse(&errs[10..]) < 0.2);
    let counts: Vec<usize> = reports.iter().map(|r| r.n_particles).collect();
    let mean = counts.iter().sum::<usize>() as f64 / counts.len() as f64;
    assert!(mean < 400.0, "{counts:?}");
    assert!(counts.iter().all(|&n| (64..=512).contains(&n)));

    // Recovery: a filter tracking the truth whose frames suddenly come from
    // another room sees the likelihood fall and injects particles.
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let truth = start_pose(&w);
    let config = FilterConfig {
        recovery: Some(recovery::RecoveryParams::default()),
        sampling: SamplingParams {
            rays: 256,
            ..Default::default()
        },
        ..Default::default()
    };
    let floor = init::floor_voxels(&w.map, w.map.db().row(0), 0.9).unwrap();
    let sampler = FloorSampler::new(&w.map, &floor, FloorParams::default());
    let init = local_init(&truth, 256, 0.1, 0.05, &mut rng);
    let mut f = Filter::new(&w.map, w.caster.clone(), intrinsics(), config, init)
        .unwrap()
        .with_injection(sampler);
    let mut tracking = 0;
    for _ in 0..5 {
        let frame = render(&w, &truth, 0.5, &mut rng);
        tracking += f.step(&Pose::identity(), &frame).unwrap().injected;
    }
    // Frame-to-frame noise in the likelihood injects a few at most.
    assert!(tracking <= 12, "{tracking}");
    let [x, y] = w.scene.free_spots[4];
    let elsewhere = level_camera(Vector3::new(x, y, 1.5), 2.0);
    let mut injected = 0;
    for _ in 0..3 {
        let frame = render(&w, &elsewhere, 0.5, &mut rng);
        injected += f.step(&Pose::identity(), &frame).unwrap().injected;
    }
    assert!(injected > 4 * tracking.max(10), "{injected} vs {tracking}");
}

/// Rooms (index by 4 m x 4 m cell) holding furniture of each kind.
fn rooms_with(w: &World, label: u32) -> Vec<(i32, i32)> {
    let mut v: Vec<(i32, i32)> = w
        .scene
        .cells
        .iter()
        .zip(&w.scene.labels)
        .filter(|(_, l)| **l == label)
        .map(|(c, _)| room_of(c[0] as f64 * 0.05, c[1] as f64 * 0.05))
        .collect();
    v.sort();
    v.dedup();
    v
}

fn room_of(x: f64, y: f64) -> (i32, i32) {
    ((x / 4.0).floor() as i32, (y / 4.0).floor() as i32)
}

#[test]
fn prompt_initialization_lands_in_the_rooms_the_words_describe() {
    let w = world();
    let floor = w.map.db().row(scene::FLOOR as usize).to_vec();
    let n_rooms = w.scene.free_spots.len();
    // The kind present in the fewest (but at least one) rooms.
    let (kind, rooms) = (0..scene::FURNITURE_KINDS)
        .map(|k| (k, rooms_with(&w, scene::FURNITURE_BASE + k)))
        .filter(|(_, r)| !r.is_empty())
        .min_by_key(|(_, r)| r.len())
        .unwrap();
    assert!(rooms.len() < n_rooms, "kind {kind} is everywhere");
    let words = vec![
        w.map
            .db()
            .row((scene::FURNITURE_BASE + kind) as usize)
            .to_vec(),
    ];
    let params = PromptParams {
        radius: 1.0,
        ..Default::default()
    };
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    let ps = prompt_init(
        &w.map,
        &floor,
        &words,
        &FloorParams::default(),
        &params,
        500,
        &mut rng,
    )
    .unwrap();
    assert_eq!(ps.len(), 500);
    // The paper's count ignores walls, so floor just behind a wall from the
    // objects may match too: every particle must be near the objects, and
    // most in the rooms that hold them.
    let objects: Vec<[f64; 2]> = w
        .scene
        .cells
        .iter()
        .zip(&w.scene.labels)
        .filter(|(_, l)| **l == scene::FURNITURE_BASE + kind)
        .map(|(c, _)| [(c[0] as f64 + 0.5) * 0.05, (c[1] as f64 + 0.5) * 0.05])
        .collect();
    let mut inside = 0;
    for p in &ps {
        let t = p.pose.translation.vector;
        let near = objects
            .iter()
            .any(|o| (o[0] - t.x).hypot(o[1] - t.y) <= params.radius + 0.1);
        assert!(near, "particle at {t} far from every object of kind {kind}");
        inside += rooms.contains(&room_of(t.x, t.y)) as usize;
        assert!((t.z - (0.05 + 1.5)).abs() < 1e-9, "camera height: {}", t.z);
    }
    assert!(inside >= 400, "{inside} of 500 in {rooms:?}");
    // A word no voxel matches: a clear error, not an empty set.
    let mut odd = vec![0f32; DIM];
    odd[0] = 1.0;
    assert!(matches!(
        prompt_init(
            &w.map,
            &floor,
            &[odd],
            &FloorParams::default(),
            &params,
            10,
            &mut rng
        ),
        Err(MclError::NoPromptMatch { .. })
    ));
    // Global initialization covers every room.
    let all = global_init(&w.map, &floor, &FloorParams::default(), 2000, &mut rng).unwrap();
    let mut seen: Vec<_> = all
        .iter()
        .map(|p| room_of(p.pose.translation.x, p.pose.translation.y))
        .collect();
    seen.sort();
    seen.dedup();
    assert!(seen.len() >= n_rooms, "{seen:?}");
}

#[test]
fn prompt_counts_match_a_brute_force_count() {
    let w = world();
    let floor = w.map.db().row(scene::FLOOR as usize).to_vec();
    let word = w.map.db().row(scene::FURNITURE_BASE as usize + 2).to_vec();
    let params = PromptParams {
        radius: 0.8,
        rho: 0.9,
        k: 60.0,
        k_resolution: 0.05,
    };
    let got = init::prompt_floor_voxels(&w.map, &floor, &[word], 0.9, &params).unwrap();
    // Brute force on a subsample of floor voxels: horizontal distance
    // between voxel centres (the plan cell equals the voxel here).
    let cells = w.map.cells();
    let objects: Vec<_> = cells
        .iter()
        .zip(w.map.rows())
        .filter(|(_, r)| **r == scene::FURNITURE_BASE + 2)
        .map(|(c, _)| *c)
        .collect();
    let mut checked = 0;
    for (leaf, c) in cells.iter().enumerate().step_by(97) {
        if w.map.rows()[leaf] != scene::FLOOR {
            continue;
        }
        let n = objects
            .iter()
            .filter(|o| {
                let (dx, dy) = ((o[0] - c[0]) as f64 * 0.05, (o[1] - c[1]) as f64 * 0.05);
                dx * dx + dy * dy <= 0.8 * 0.8 + 1e-9
            })
            .count();
        assert_eq!(
            got.binary_search(&leaf).is_ok(),
            n >= 60,
            "leaf {leaf}: {n}"
        );
        checked += 1;
    }
    assert!(checked > 100);
}

/// A radius wider than the map counts every voxel of the map: all the
/// word's voxels are near every floor voxel, one more than all of them
/// near none; and a radius of 1e308 is searched (and told) as the map's
/// diagonal, not squared to infinity or printed in 309 digits.
#[test]
fn a_radius_wider_than_the_map_counts_the_whole_map() {
    let w = world();
    let floor = w.map.db().row(scene::FLOOR as usize).to_vec();
    let word = w.map.db().row(scene::FURNITURE_BASE as usize + 2).to_vec();
    let total = w
        .map
        .rows()
        .iter()
        .filter(|&&r| r == scene::FURNITURE_BASE + 2)
        .count();
    assert!(total > 0);
    let n_floor = w.map.rows().iter().filter(|&&r| r == scene::FLOOR).count();
    for radius in [1e308, f64::MAX, 1e4] {
        let params = |k: usize| PromptParams {
            radius,
            rho: 0.9,
            k: k as f64,
            k_resolution: 0.05,
        };
        let all = init::prompt_floor_voxels(
            &w.map,
            &floor,
            std::slice::from_ref(&word),
            0.9,
            &params(total),
        )
        .unwrap();
        assert_eq!(all.len(), n_floor, "radius {radius}");
        match init::prompt_floor_voxels(
            &w.map,
            &floor,
            std::slice::from_ref(&word),
            0.9,
            &params(total + 1),
        ) {
            Err(
                e @ MclError::NoPromptMatch {
                    radius: r,
                    whole_map: true,
                    ..
                },
            ) => {
                let (lo, hi) = w.map.world_bounds().unwrap();
                let diag = (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
                assert!((r - diag).abs() < 0.1, "{r} against {diag}");
                let text = e.to_string();
                assert!(text.len() < 200 && text.contains("the whole map"), "{text}");
            }
            other => panic!("radius {radius}: {other:?}"),
        }
    }
}

#[test]
fn a_caster_of_another_map_or_a_failed_cast_is_an_error() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let truth = start_pose(&w);
    let init = local_init(&truth, 32, 0.3, 0.3, &mut rng);
    // A caster built from other voxels (one fewer).
    let cells = w.map.cells();
    let other = SensorModel::embree_caster(w.scene.resolution as f32, &cells[1..]).unwrap();
    let err = Filter::new(
        &w.map,
        Arc::new(other),
        intrinsics(),
        FilterConfig::default(),
        init.clone(),
    )
    .err()
    .expect("a mismatched caster is refused");
    assert!(
        matches!(err, MclError::CasterMismatch { caster, map } if caster + 1 == map),
        "{err}"
    );
    // A cast that fails inside Embree: the step fails and the particles
    // stay as they were.
    let caster = Arc::new(SensorModel::embree_caster(w.scene.resolution as f32, &cells).unwrap());
    let mut f = Filter::new(
        &w.map,
        caster.clone(),
        intrinsics(),
        FilterConfig::default(),
        init,
    )
    .unwrap();
    let before = f.particles().to_vec();
    let frame = render(&w, &truth, 0.5, &mut rng);
    caster.inject_trace_error_for_test();
    let err = f.step(&Pose::identity(), &frame).unwrap_err();
    assert!(
        matches!(&err, MclError::Cast(m) if m.contains("injected")),
        "{err}"
    );
    assert_eq!(f.particles(), &before[..]);
    // The filter goes on.
    assert!(f.step(&Pose::identity(), &frame).is_ok());
}

#[test]
fn bad_input_gives_clear_errors() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let truth = start_pose(&w);
    let init = local_init(&truth, 32, 0.3, 0.3, &mut rng);
    let mut f = Filter::new(
        &w.map,
        w.caster.clone(),
        intrinsics(),
        FilterConfig::default(),
        init,
    )
    .unwrap();
    let before = f.particles().to_vec();
    let mut config = FilterConfig::default();
    config.sampling.boundary_margin_width = f32::NAN;
    assert!(matches!(
        Filter::new(
            &w.map,
            w.caster.clone(),
            intrinsics(),
            config,
            before.clone()
        ),
        Err(MclError::BadParam {
            name: "sampling.boundary_margin_width",
            ..
        })
    ));
    for (e, field) in [
        (
            EarlyReject {
                every: 1,
                ratio: 0.85,
            },
            "sensor.early_reject.every",
        ),
        (
            EarlyReject {
                every: 4,
                ratio: f32::NAN,
            },
            "sensor.early_reject.ratio",
        ),
        (
            EarlyReject {
                every: 4,
                ratio: 1.5,
            },
            "sensor.early_reject.ratio",
        ),
    ] {
        let mut config = FilterConfig::default();
        config.sensor.early_reject = Some(e);
        let r = Filter::new(
            &w.map,
            w.caster.clone(),
            intrinsics(),
            config,
            before.clone(),
        );
        assert!(
            matches!(r, Err(MclError::BadParam { name, .. }) if name == field),
            "{e:?}"
        );
    }
    let frame = render(&w, &truth, 0.5, &mut rng);
    let nan = Pose::from_parts(
        Translation3::new(0.0, f64::NAN, 0.0),
        UnitQuaternion::identity(),
    );
    assert!(matches!(
        f.step(&nan, &frame),
        Err(MclError::BadOdometry(_))
    ));
    let wrong = crate::frame::DenseFeatures {
        width: frame.width,
        height: frame.height,
        dim: 16,
        data: vec![0.5; frame.data.len() / 2],
    };
    assert_eq!(
        f.step(&Pose::identity(), &wrong).unwrap_err(),
        MclError::DimMismatch {
            expected: DIM,
            got: 16
        }
    );
    let small = crate::frame::DenseFeatures {
        width: 10,
        ..frame.clone()
    };
    assert!(matches!(
        f.step(&Pose::identity(), &small),
        Err(MclError::ImageSize { .. })
    ));
    assert_eq!(
        f.particles(),
        &before[..],
        "errors leave the particles alone"
    );
    // A frame of all-zero features (no information): weights stay finite.
    let blank = crate::frame::DenseFeatures {
        data: vec![0.0; frame.data.len()],
        ..frame.clone()
    };
    let rep = f.step(&Pose::identity(), &blank).unwrap();
    assert!(
        rep.estimate
            .translation
            .vector
            .iter()
            .all(|v| v.is_finite())
    );
    // No floor: "floor" feature unlike every row.
    let mut odd = vec![0f32; DIM];
    odd[3] = 1.0;
    assert_eq!(
        global_init(&w.map, &odd, &FloorParams::default(), 10, &mut rng).unwrap_err(),
        MclError::NoFloor { rho: 0.9 }
    );
    assert!(matches!(
        global_init(&w.map, &[1.0; 3], &FloorParams::default(), 10, &mut rng),
        Err(MclError::PromptDim { .. })
    ));
}

#[test]
fn contrast_rescales_each_pixel_to_its_best_and_worst_row() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let frame = render(&w, &start_pose(&w), 0.3, &mut rng);
    let pixels = vec![(10, 10), (50, 40), (90, 70)];
    let plain = SimilarityTable::new(&frame, &pixels, w.map.db(), false).unwrap();
    let c = SimilarityTable::new(&frame, &pixels, w.map.db(), true).unwrap();
    let k = w.map.db().len();
    for j in 0..pixels.len() {
        let row: Vec<f32> = (0..k).map(|r| plain.get(j, r)).collect();
        let (lo, hi) = row
            .iter()
            .fold((f32::MAX, f32::MIN), |(a, b), &x| (a.min(x), b.max(x)));
        for (r, &x) in row.iter().enumerate() {
            let want = (x - lo) / (hi - lo);
            assert!((c.get(j, r) - want).abs() < 1e-6);
        }
        assert!((0..k).any(|r| c.get(j, r) == 1.0) && (0..k).any(|r| c.get(j, r) == 0.0));
    }
}

#[test]
fn misses_score_the_miss_parameter() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let truth = start_pose(&w);
    let frame = render(&w, &truth, 0.0, &mut rng);
    let pixels = vec![(10, 10), (50, 40), (90, 70)];
    let table = SimilarityTable::new(&frame, &pixels, w.map.db(), false).unwrap();
    // A camera outside the building looking away from it: every ray misses.
    let outside = Particle::new(
        level_camera(Vector3::new(-5.0, 4.0, 1.5), std::f64::consts::PI),
        1.0,
    );
    for miss in [0.0, -0.5, 0.25] {
        let mut sensor = SensorModel::new(
            w.caster.clone(),
            w.map.rows().into(),
            w.map.grid().origin,
            intrinsics(),
            SensorParams {
                miss_score: miss,
                ..Default::default()
            },
        );
        let l = sensor
            .likelihoods(&[outside, Particle::new(truth, 1.0)], &pixels, &table)
            .to_vec();
        assert!((l[0] - miss).abs() < 1e-6, "{l:?}");
        // Noise-free features at the truth: cosine 1 on every ray.
        assert!((l[1] - 1.0).abs() < 1e-5, "{l:?}");
    }
}

#[test]
fn full_motion_noise_has_the_stated_spread() {
    let m = MotionModel {
        mode: MotionMode::Full,
        ..Default::default()
    };
    let start = level_camera(Vector3::new(1.0, 1.0, 1.0), 0.7);
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    let n = 20000;
    let (mut st, mut sr) = (Vector3::zeros(), 0.0);
    for _ in 0..n {
        let p = m.sample(&start, &Pose::identity(), &mut rng);
        let local = start.inverse() * p;
        st += local
            .translation
            .vector
            .component_mul(&local.translation.vector);
        sr += local.rotation.angle().powi(2);
    }
    let st = (st / n as f64).map(f64::sqrt);
    assert!(st.iter().all(|s| (s - 0.10).abs() < 0.004), "{st}");
    // Rotation angle of a 3-D Gaussian rotation vector: E[angle^2] = 3 sigma^2.
    let sr = (sr / n as f64 / 3.0).sqrt();
    assert!((sr - 6f64.to_radians()).abs() < 0.004, "{sr}");
}

#[test]
fn two_words_narrow_the_prompt_and_reinitialize_replaces_the_set() {
    let w = world();
    let floor = w.map.db().row(scene::FLOOR as usize).to_vec();
    let params = PromptParams {
        radius: 1.0,
        ..Default::default()
    };
    let word = |k: u32| {
        w.map
            .db()
            .row((scene::FURNITURE_BASE + k) as usize)
            .to_vec()
    };
    let present: Vec<u32> = (0..scene::FURNITURE_KINDS)
        .filter(|&k| !rooms_with(&w, scene::FURNITURE_BASE + k).is_empty())
        .collect();
    let (a, b) = (present[0], present[1]);
    let one = init::prompt_floor_voxels(&w.map, &floor, &[word(a)], 0.9, &params).unwrap();
    // Every voxel matching both words matches the first alone (or none
    // matches both: a clear error).
    match init::prompt_floor_voxels(&w.map, &floor, &[word(a), word(b)], 0.9, &params) {
        Ok(two) => {
            assert!(two.len() <= one.len());
            assert!(two.iter().all(|l| one.binary_search(l).is_ok()));
        }
        Err(e) => assert!(matches!(e, MclError::NoPromptMatch { .. }), "{e}"),
    }
    assert_eq!(
        init::prompt_floor_voxels(&w.map, &floor, &[], 0.9, &params),
        Err(MclError::EmptyPrompt)
    );

    let mut rng = ChaCha8Rng::seed_from_u64(14);
    let truth = start_pose(&w);
    let init = local_init(&truth, 64, 0.3, 0.3, &mut rng);
    let mut f = Filter::new(
        &w.map,
        w.caster.clone(),
        intrinsics(),
        FilterConfig::default(),
        init,
    )
    .unwrap();
    let fresh = global_init(&w.map, &floor, &FloorParams::default(), 100, &mut rng).unwrap();
    assert_eq!(f.reinitialize(Vec::new()), Err(MclError::NoParticles));
    f.reinitialize(fresh.clone()).unwrap();
    assert_eq!(f.particles().len(), 100);
    assert!(
        f.particles()
            .iter()
            .all(|p| (p.weight - 0.01).abs() < 1e-12)
    );
}

/// A camera circling spot `a` for `before` frames, then (kidnapped: the
/// odometry reports an ordinary step) circling spot `b`; the odometry has
/// the paper's noise. Returns ground truth and odometry increments.
fn kidnap_path(
    w: &World,
    a: usize,
    b: usize,
    before: usize,
    total: usize,
    rng: &mut ChaCha8Rng,
) -> (Vec<Pose>, Vec<Pose>) {
    let r = 0.13 / 8f64.to_radians();
    let circle = |spot: [f64; 2], i: usize| {
        let ang = i as f64 * 8f64.to_radians();
        let p = Vector3::new(
            spot[0] + r * ang.sin() - 0.2,
            spot[1] - r * ang.cos() + r - 0.3,
            1.5,
        );
        level_camera(p, ang)
    };
    let gt: Vec<Pose> = (0..total)
        .map(|i| {
            if i < before {
                circle(w.scene.free_spots[a], i)
            } else {
                circle(w.scene.free_spots[b], i)
            }
        })
        .collect();
    let odom = gt
        .windows(2)
        .enumerate()
        .map(|(i, g)| {
            // At the kidnap the odometry saw an ordinary step on the circle.
            let inc = if i + 1 == before {
                gt[i - 1].inverse() * gt[i]
            } else {
                g[0].inverse() * g[1]
            };
            let mut n = || rng.sample::<f64, _>(StandardNormal);
            let t = Vector3::new(n() * 0.1, 0.0, n() * 0.1);
            let q = UnitQuaternion::from_axis_angle(&Vector3::y_axis(), n() * 6f64.to_radians());
            inc * Pose::from_parts(Translation3::from(t), q)
        })
        .collect();
    (gt, odom)
}

/// The kidnapped robot: tracked for 15 frames, teleported to another room,
/// 45 more frames. With recovery on (augmented MCL injecting floor poses),
/// the filter must be back within 0.5 m for good within 30 frames in at
/// least 9 of 10 seeded runs, and its confidence must fall while it is lost.
#[test]
fn a_kidnapped_camera_is_found_again() {
    let w = world();
    let (before, total) = (15, 60);
    let floor = init::floor_voxels(&w.map, w.map.db().row(0), 0.9).unwrap();
    let mut found = 0;
    let mut report = Vec::new();
    for seed in 0..10u64 {
        let mut rng = ChaCha8Rng::seed_from_u64(100 + seed);
        let b = 1 + seed as usize % (w.scene.free_spots.len() - 1);
        let (gt, odom) = kidnap_path(&w, 0, b, before, total, &mut rng);
        let config = FilterConfig {
            recovery: Some(recovery::RecoveryParams::default()),
            sampling: SamplingParams {
                rays: 256,
                ..Default::default()
            },
            seed,
            ..Default::default()
        };
        let sampler = FloorSampler::new(&w.map, &floor, FloorParams::default());
        let init = local_init(&gt[0], 512, 0.3, 17f64.to_radians(), &mut rng);
        let mut f = Filter::new(&w.map, w.caster.clone(), intrinsics(), config, init)
            .unwrap()
            .with_injection(sampler);
        let mut errs = Vec::new();
        let mut conf = Vec::new();
        for (g, inc) in gt[1..].iter().zip(&odom) {
            let frame = render(&w, g, 0.5, &mut rng);
            let rep = f.step(inc, &frame).unwrap();
            errs.push((rep.estimate.translation.vector - g.translation.vector).norm());
            conf.push(rep.confidence);
        }
        // errs[i] is frame i + 1; the kidnap is at frame `before`.
        let k = before - 1;
        assert!(
            errs[5..k].iter().all(|&e| e < 0.5),
            "tracked before: {errs:.2?}"
        );
        // Back for good: the first frame from which every error is < 0.5 m.
        let back = (k..errs.len()).find(|&i| errs[i..].iter().all(|&e| e < 0.5));
        let lost_conf = conf[k..back.unwrap_or(errs.len())]
            .iter()
            .cloned()
            .fold(f64::INFINITY, f64::min);
        let tracked_conf = conf[5..k].iter().cloned().fold(f64::INFINITY, f64::min);
        report.push((seed, back.map(|i| i - k), tracked_conf, lost_conf));
        if back.is_some_and(|i| i - k <= 30) {
            found += 1;
        }
    }
    println!("(seed, frames to re-localize, confidence tracking, lost): {report:.2?}");
    assert!(found >= 9, "{found} of 10 re-localized: {report:.2?}");
    // Lost means less sure than while tracking: the confidence falls by
    // at least 5 points in every run (measured: from 1.00 to 0.76-0.94).
    for &(seed, _, tracked, lost) in &report {
        assert!(
            lost <= tracked - 0.05,
            "seed {seed}: confidence {lost:.2} while lost, {tracked:.2} tracking"
        );
    }
}

/// Frames dropped (their odometry arrives composed with the next frame's),
/// a frame delivered twice (identity increment), and an odometry jump of
/// 0.6 m: the filter, with recovery on, tracks to the end.
#[test]
fn dropped_and_repeated_frames_and_odometry_jumps_are_survived() {
    let w = world();
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let (gt, odom) = path(&w, &mut rng);
    let floor = init::floor_voxels(&w.map, w.map.db().row(0), 0.9).unwrap();
    let config = FilterConfig {
        recovery: Some(recovery::RecoveryParams::default()),
        sampling: SamplingParams {
            rays: 256,
            ..Default::default()
        },
        seed: 21,
        ..Default::default()
    };
    let init = local_init(&gt[0], 512, 0.3, 17f64.to_radians(), &mut rng);
    let mut f = Filter::new(&w.map, w.caster.clone(), intrinsics(), config, init)
        .unwrap()
        .with_injection(FloorSampler::new(&w.map, &floor, FloorParams::default()));
    let jump = Pose::from_parts(Translation3::new(0.6, 0.0, 0.0), UnitQuaternion::identity());
    let mut errs = Vec::new();
    let mut pending = Pose::identity();
    for (i, (g, inc)) in gt[1..].iter().zip(&odom).enumerate() {
        let frame_no = i + 1;
        pending *= inc;
        // Frames 20 and 21 never arrive.
        if frame_no == 20 || frame_no == 21 {
            continue;
        }
        let increment = if frame_no == 40 {
            pending * jump
        } else {
            pending
        };
        pending = Pose::identity();
        let frame = render(&w, g, 0.5, &mut rng);
        let rep = f.step(&increment, &frame).unwrap();
        errs.push((
            frame_no,
            (rep.estimate.translation.vector - g.translation.vector).norm(),
        ));
        if frame_no == 30 {
            // The same frame again: no motion.
            let rep = f.step(&Pose::identity(), &frame).unwrap();
            errs.push((
                frame_no,
                (rep.estimate.translation.vector - g.translation.vector).norm(),
            ));
        }
    }
    let tail: Vec<f64> = errs
        .iter()
        .filter(|(n, _)| *n >= 50)
        .map(|&(_, e)| e)
        .collect();
    println!("errors by frame: {errs:.2?}");
    assert!(rmse(&tail) < 0.2, "last 10 frames: RMSE {}", rmse(&tail));
    let around_drop: Vec<f64> = errs
        .iter()
        .filter(|(n, _)| (22..=35).contains(n))
        .map(|&(_, e)| e)
        .collect();
    assert!(around_drop.iter().all(|&e| e < 0.5), "{errs:.2?}");
    // Back within 4 frames of the 0.6 m jump (frame 40).
    assert!(
        errs.iter()
            .filter(|(n, _)| (44..50).contains(n))
            .all(|&(_, e)| e < 0.2),
        "{errs:.2?}"
    );
}

/// Same seed, same trajectory, to the bit, whether the step runs on one
/// thread or two.
#[test]
fn the_same_seed_gives_the_same_trajectory_on_one_thread_and_two() {
    let w = world();
    let config = FilterConfig {
        sampling: SamplingParams {
            rays: 256,
            ..Default::default()
        },
        recovery: Some(recovery::RecoveryParams::default()),
        seed: 5,
        ..Default::default()
    };
    let on = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let (errs, reports) = run(&w, config, 256, 5);
            let poses: Vec<[f64; 7]> = reports
                .iter()
                .map(|r| {
                    let t = r.estimate.translation.vector;
                    let q = r.estimate.rotation.coords;
                    [t.x, t.y, t.z, q.x, q.y, q.z, q.w]
                })
                .collect();
            (errs, poses)
        })
    };
    let one = on(1);
    let two = on(2);
    let bits = |v: &[[f64; 7]]| -> Vec<u64> { v.iter().flatten().map(|x| x.to_bits()).collect() };
    assert_eq!(bits(&one.1), bits(&two.1));
    assert_eq!(one.0, two.0);
}

/// Rooms keep bricks of edge 4; a map more than 100 m across (a street)
/// gets bricks of edge 8 with the high build quality, and its caster still
/// hits what the reference DDA hits.
#[test]
fn large_maps_get_the_outdoor_scene_and_cast_the_same() {
    use crate::geometry::Ray;
    use crate::map::Cell;
    use crate::raycast::{BrickEdge, BuildQuality, Geometry};
    // A road 150 m long (0.1 m cells, 3 m wide) with a kerb wall along it.
    let mut street: Vec<Cell> = Vec::new();
    for i in 0..1500 {
        for j in 0..30 {
            street.push([i, j, 0]);
        }
        for k in 1..15 {
            street.push([i, 30, k]);
        }
    }
    let room: Vec<Cell> = street.iter().copied().filter(|c| c[0] < 200).collect();
    let opts = |cells: &[Cell]| SensorModel::filter_build_options(0.1, cells);
    assert_eq!(opts(&room).geometry, Geometry::Bricks(BrickEdge::Four));
    assert_eq!(opts(&room).quality, BuildQuality::Medium);
    assert_eq!(opts(&street).geometry, Geometry::Bricks(BrickEdge::Eight));
    assert_eq!(opts(&street).quality, BuildQuality::High);
    let fast = SensorModel::embree_caster(0.1, &street).unwrap();
    let reference = ReferenceCaster::new(0.1, &street);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let rays: Vec<Ray> = (0..2000)
        .map(|_| {
            let o = [
                rng.random_range(1.0f32..149.0),
                rng.random_range(0.2f32..2.8),
                1.6,
            ];
            let a: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let down: f32 = rng.random_range(-0.6..0.3);
            Ray::new(o, [a.cos(), a.sin(), down])
        })
        .collect();
    let (got, want) = (fast.cast_vec(&rays), reference.cast_vec(&rays));
    let mut hits = 0;
    for ((r, g), w) in rays.iter().zip(&got).zip(&want) {
        assert_eq!(g.is_hit(), w.is_hit(), "{r:?}: {g:?} vs {w:?}");
        if w.is_hit() {
            assert!(
                (g.t - w.t).abs() < 1e-3 * w.t.max(1.0),
                "{r:?}: {g:?} vs {w:?}"
            );
            hits += 1;
        }
    }
    // About 37 % hit (the rest leave the 3 m road sideways or look up).
    assert!(hits > 600, "{hits}");
}

/// A frame that hands its features over one by one only (no
/// [`crate::frame::FrameFeatures::grid_features`]).
struct OneByOne<'a>(&'a crate::frame::DenseFeatures);

impl crate::frame::FrameFeatures for OneByOne<'_> {
    fn width(&self) -> u32 {
        self.0.width
    }
    fn height(&self) -> u32 {
        self.0.height
    }
    fn dim(&self) -> usize {
        self.0.dim
    }
    fn feature(&self, u: u32, v: u32, out: &mut [f32]) {
        self.0.feature(u, v, out)
    }
}

/// The products the sampler keeps from its clustering give the table the
/// direct computation gives (with and without contrast), and the same
/// pixels, whether the frame's grid features are multiplied in place
/// (stride 1 of a dense image) or copied out one by one (stride 1 and 4).
#[test]
fn tables_from_the_samplers_products_equal_direct_tables() {
    let w = world();
    let db = w.map.db();
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let frame = render(&w, &start_pose(&w), 0.5, &mut rng);
    assert!(frame.grid_features(1).is_some() && frame.grid_features(4).is_none());
    for stride in [1, 4] {
        let params = SamplingParams {
            rays: 256,
            stride,
            ..Default::default()
        };
        let draw = |f: &dyn FrameFeatures| {
            sampling::sample(f, db, &params, &mut ChaCha8Rng::seed_from_u64(5)).unwrap()
        };
        let (a, b) = (draw(&frame), draw(&OneByOne(&frame)));
        assert_eq!(a.pixels, b.pixels, "stride {stride}");
        assert!(a.pixels.len() > 100, "{}", a.pixels.len());
        assert!(a.scores.is_some() && b.scores.is_some());
        for contrast in [false, true] {
            let direct = SimilarityTable::new(&frame, &a.pixels, db, contrast).unwrap();
            for (s, f) in [(&a, &frame as &dyn FrameFeatures), (&b, &OneByOne(&frame))] {
                let t = SimilarityTable::of_sample(f, s, db, contrast).unwrap();
                assert_eq!(t.pixels(), direct.pixels());
                for j in 0..t.pixels() {
                    for k in 0..db.len() {
                        let (x, y) = (t.get(j, k), direct.get(j, k));
                        assert!(
                            (x - y).abs() <= 1e-5,
                            "{stride} {contrast} {j} {k}: {x} {y}"
                        );
                    }
                }
            }
        }
    }
    // Uniform sampling clusters nothing and keeps no products; its table
    // is computed directly.
    let params = SamplingParams {
        strategy: SamplingStrategy::Uniform,
        rays: 64,
        ..Default::default()
    };
    let s = sampling::sample(&frame, db, &params, &mut rng).unwrap();
    assert!(s.scores.is_none());
    let t = SimilarityTable::of_sample(&frame, &s, db, false).unwrap();
    assert_eq!(
        t,
        SimilarityTable::new(&frame, &s.pixels, db, false).unwrap()
    );
}

/// Every tuned filter passes [`FilterConfig::validate`], and each value a
/// JSON configuration could carry past the command lines' bounds is
/// refused naming its field (`--set sampling.rays=100000000000` aborted on
/// an 800 GB allocation; `sensor.miss_score=5` ran).
#[test]
fn configurations_out_of_bounds_are_refused_by_field() {
    use crate::mcl::kld::KldParams;
    use crate::mcl::preset::FilterPreset;
    use crate::mcl::recovery::RecoveryParams;
    for p in FilterPreset::ALL {
        p.config().validate().unwrap();
    }
    let with_all = FilterConfig {
        kld: Some(KldParams::default()),
        recovery: Some(RecoveryParams::default()),
        ..FilterConfig::default()
    };
    with_all.validate().unwrap();
    type Edit = fn(&mut FilterConfig);
    let cases: [(&str, Edit); 14] = [
        ("sampling.rays", |c| c.sampling.rays = 100_000_000_000),
        ("sampling.rays", |c| c.sampling.rays = 0),
        ("sampling.stride", |c| c.sampling.stride = 0),
        ("sensor.miss_score", |c| c.sensor.miss_score = 5.0),
        ("sensor.max_range", |c| c.sensor.max_range = -1.0),
        ("motion.sigma_translation", |c| {
            c.motion.sigma_translation = 1e300
        }),
        ("motion.sigma_rotation", |c| c.motion.sigma_rotation = 7.0),
        ("resample.ess_fraction", |c| c.resample.ess_fraction = -0.5),
        ("estimate.radius", |c| c.estimate.radius = -1.0),
        ("estimate.radius", |c| c.estimate.radius = 0.0),
        ("anneal", |c| {
            c.anneal = Some(crate::mcl::Anneal {
                layers: 4_000_000_000,
                ..crate::mcl::Anneal::default()
            })
        }),
        ("kld.min_particles", |c| {
            c.kld = Some(KldParams {
                max_particles: 100_000_000_000,
                ..KldParams::default()
            })
        }),
        ("recovery.alpha_slow", |c| {
            c.recovery = Some(RecoveryParams {
                alpha_slow: 0.5,
                alpha_fast: 0.1,
                ..RecoveryParams::default()
            })
        }),
        ("recovery.candidates", |c| {
            c.recovery = Some(RecoveryParams {
                candidates: 0,
                ..RecoveryParams::default()
            })
        }),
    ];
    for (field, edit) in cases {
        let mut c = FilterConfig::default();
        edit(&mut c);
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains(field), "{field}: {e}");
    }
    // Unlimited range, resampling every step and an estimate over all
    // particles stay allowed.
    let mut c = FilterConfig::default();
    c.sensor.max_range = f32::INFINITY;
    c.resample.ess_fraction = 7.0;
    c.estimate.radius = f64::INFINITY;
    c.validate().unwrap();
}
