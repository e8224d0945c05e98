//! SeDAR* and SIMP*: the two semantic MCL baselines of Table I's 2-D
//! block, as sensor models on the common floor plan
//! ([`crate::map::floorplan`]), behind the same particle filter pieces as
//! OMCL (motion, pixel sampling, resampling, estimate, local start).
//!
//! Both published methods work on class labels, not features, so both
//! starred versions label the plan and the pixels the same way: a plan
//! column's label is the class (of the sequence's class table) most
//! similar to its averaged feature, a pixel's label the class most similar
//! to its feature. Both sample their pixels as OMCL does (stratified over
//! the frame's clusters; 2048 a frame, [`BaselineParams::pixels`], where
//! the 2-D OMCL filter takes 8192), and both combine per-pixel
//! likelihoods as a product, tempered the way AMCL tempers its beams:
//! `log w = (beams / N) sum_j log p_j` with `beams` 30 (AMCL's
//! `laser_max_beams`), so that about as much evidence enters a step as a
//! 30-beam scan gives.
//!
//! **SeDAR\*** (Mendez et al., ICRA 2018, "SeDAR - Semantic Detection and
//! Ranging"; IJCV 2020): particles cast rays in a semantic floor plan and
//! compare the label the ray reaches with the label observed in that
//! direction; the authors show that the semantic term alone (no range)
//! localizes about as well as with range, and that mode is used here
//! (monocular images, like OMCL's). Adaptations: SeDAR's floor plans carry
//! a few architectural labels (wall, door, window); here the ray ends at the
//! first occupied column of the averaged plan (the same planar ray as
//! OMCL's 2-D mode, [`crate::raycast::PlanarCaster`]) and its label is any
//! of the table's classes. Per ray
//! `p = (1 - z_rand) [label(hit) = label(pixel)] + z_rand / C` (C classes),
//! a ray that reaches nothing counting as a mismatch and a pixel without
//! a class (a zero feature: a label the table lacks) skipped.
//!
//! **SIMP\*** (Zimmerman et al., 2023, "Constructing Metric-Semantic Maps
//! using Floor Plan Priors for Long-Term Indoor Localization"): objects
//! detected in 3-D from the camera are placed in the world by each
//! particle and scored by their distance to the map's objects of the same
//! class. Adaptations: the map's objects are the plan's columns of each
//! class, and the detections are the sampled pixels with their depth (the
//! RGB-D frame's, where SIMP estimates depth from monocular 3-D detection);
//! each pixel's 3-D point, placed by the particle and projected to the
//! plane, is scored with a per-class likelihood field:
//! `p = (1 - z_rand) exp(-d^2 / (2 sigma^2)) + z_rand`, `d` the distance (m)
//! to the nearest column of the pixel's class (capped at `max_distance`;
//! pixels without depth or of a class the plan lacks, such as floor and
//! ceiling outside the plan's height band, are skipped). SIMP's detector
//! sees objects only so far; [`BaselineParams::max_depth`] skips pixels
//! deeper than a range too (unset in Table I's rows: the synthetic
//! rooms' true depth is exact at every range).

use nalgebra::Vector3;

use super::MclError;
use super::particles::Particle;
use crate::geometry::{Intrinsics, Pose, Ray};
use crate::map::{FeatureDb, FloorPlan};
use crate::raycast::{PlanarCaster, RayCaster};

/// Which baseline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Baseline {
    Sedar,
    Simp,
}

impl Baseline {
    /// The method's name, starred as in Table I: what a message names.
    pub fn label(self) -> &'static str {
        match self {
            Baseline::Sedar => "SeDAR*",
            Baseline::Simp => "SIMP*",
        }
    }

    /// The row name of Table I: the method on ground-truth labels.
    pub fn name(self) -> &'static str {
        match self {
            Baseline::Sedar => "SeDAR*_GT",
            Baseline::Simp => "SIMP*_GT",
        }
    }
}

/// Parameters of both baselines.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BaselineParams {
    /// Weight of the uniform (random) part of each pixel's likelihood.
    pub z_rand: f64,
    /// SIMP*: standard deviation of the likelihood field, metres.
    pub sigma: f64,
    /// SIMP*: distances are capped here, metres.
    pub max_distance: f64,
    /// Effective independent pixels per step (AMCL's `laser_max_beams`).
    pub beams: f64,
    /// Pixels sampled a frame (the filter's stratified sampling, with
    /// this count instead of the OMCL filter's). 2048, the count both
    /// baselines were run and reported with; with the 2-D OMCL filter's
    /// 8192 ([`super::FLOOR_PLAN_RAYS`]) SeDAR* lost six of ten held-out
    /// sequences, with 2048 one (docs/table1.md, "More pixels, sharper").
    #[serde(default = "default_pixels")]
    pub pixels: usize,
    /// SIMP\*: pixels deeper than this (z-depth, metres) are not placed,
    /// as a detector sees objects only so far; `None` (the default, and
    /// Table I's rows): every pixel with a depth.
    #[serde(default)]
    pub max_depth: Option<f64>,
}

fn default_pixels() -> usize {
    BaselineParams::default().pixels
}

impl Default for BaselineParams {
    fn default() -> Self {
        BaselineParams {
            z_rand: 0.1,
            sigma: 0.2,
            max_distance: 2.0,
            beams: 30.0,
            pixels: 2048,
            max_depth: None,
        }
    }
}

/// Label of a column or pixel that has none.
pub const NO_LABEL: u16 = u16::MAX;

/// A floor plan's columns labelled by class, with a distance field per
/// class.
#[derive(Debug, Clone)]
pub struct LabelledPlan {
    resolution: f64,
    /// World x, y of the corner of grid cell `lo`.
    corner: [f64; 2],
    lo: [i32; 2],
    size: [usize; 2],
    /// Label per leaf of the plan's one-layer map (leaf order).
    leaf_labels: Vec<u16>,
    /// `dist[c][y * size_x + x]`: distance (m) to the nearest column of
    /// class `c`, capped.
    dist: Vec<Vec<f32>>,
    classes: usize,
}

impl LabelledPlan {
    /// Labels the leaves of `plan`'s one-layer map `cells` (leaf order, as
    /// the caster indexes them) by the class of `classes` nearest to their
    /// row's feature. Fails on a `max_distance` that is not a positive
    /// number of metres, or whose fields (the columns' extent and
    /// `max_distance` past it) would hold more than
    /// [`crate::map::floorplan::MAX_PLAN_CELLS`] cells.
    pub fn new(
        plan: &FloorPlan,
        cells: &[crate::map::Cell],
        rows: &[u32],
        classes: &FeatureDb,
        max_distance: f64,
    ) -> Result<Self, MclError> {
        if !(max_distance.is_finite() && max_distance > 0.0) {
            return Err(MclError::BadParam {
                name: "baseline max distance",
                why: format!("{max_distance} m: expected a positive number of metres"),
            });
        }
        let row_label: Vec<u16> = (0..plan.db().len())
            .map(|r| {
                classes
                    .nearest(plan.db().row(r))
                    .ok()
                    .flatten()
                    .map_or(NO_LABEL, |(c, _)| c as u16)
            })
            .collect();
        let leaf_labels: Vec<u16> = rows.iter().map(|&r| row_label[r as usize]).collect();
        let r = plan.resolution;
        // The fields reach `max_distance` past the outermost columns, so a
        // point just outside an outer wall scores its distance to the wall
        // as one just inside does (not the cap).
        let (lo, hi) = crate::raycast::column_bounds(cells);
        let pad = (max_distance / r).ceil();
        let span = |a: usize| (hi[a] - lo[a] + 1) as f64 + 2.0 * pad;
        let most = crate::map::floorplan::MAX_PLAN_CELLS as f64;
        if span(0) * span(1) > most {
            return Err(MclError::BadParam {
                name: "baseline max distance",
                why: format!(
                    "{max_distance} m past the plan's columns makes distance fields of {} x {} \
                     cells of {r} m, more than {most} in all",
                    span(0),
                    span(1)
                ),
            });
        }
        // At most MAX_PLAN_CELLS cells: `pad` fits an i32.
        let pad = pad as i32;
        let (lo, hi) = ([lo[0] - pad, lo[1] - pad], [hi[0] + pad, hi[1] + pad]);
        let size = [(hi[0] - lo[0] + 1) as usize, (hi[1] - lo[1] + 1) as usize];
        let k = classes.len();
        let mut seeds = vec![Vec::new(); k];
        for (c, &l) in cells.iter().zip(&leaf_labels) {
            if (l as usize) < k {
                seeds[l as usize].push(((c[0] - lo[0]) as usize, (c[1] - lo[1]) as usize));
            }
        }
        let dist = seeds
            .iter()
            .map(|s| distance_field(s, size, r, max_distance))
            .collect();
        Ok(LabelledPlan {
            resolution: r,
            corner: [
                plan.origin[0] + lo[0] as f64 * r,
                plan.origin[1] + lo[1] as f64 * r,
            ],
            lo,
            size,
            leaf_labels,
            dist,
            classes: k,
        })
    }

    /// Label of leaf `leaf`.
    pub fn leaf_label(&self, leaf: u32) -> u16 {
        self.leaf_labels
            .get(leaf as usize)
            .copied()
            .unwrap_or(NO_LABEL)
    }

    /// Whether the plan has a column of class `c`.
    pub fn has_class(&self, c: u16) -> bool {
        self.dist.get(c as usize).is_some_and(|f| !f.is_empty())
    }

    /// Distance (m, capped) from world point `(x, y)` to the nearest column
    /// of class `c`; `None` when the plan has no column of that class.
    pub fn distance(&self, c: u16, x: f64, y: f64, cap: f64) -> Option<f64> {
        if !self.has_class(c) {
            return None;
        }
        let field = &self.dist[c as usize];
        let i = ((x - self.corner[0]) / self.resolution).floor();
        let j = ((y - self.corner[1]) / self.resolution).floor();
        if i < 0.0 || j < 0.0 || i >= self.size[0] as f64 || j >= self.size[1] as f64 {
            return Some(cap);
        }
        Some((field[j as usize * self.size[0] + i as usize] as f64).min(cap))
    }

    /// Number of classes.
    pub fn classes(&self) -> usize {
        self.classes
    }

    /// Lowest column index of the grid (the fields' padding included).
    pub fn lo(&self) -> [i32; 2] {
        self.lo
    }
}

/// Euclidean distance (m) to the nearest seed cell, capped at `cap`, by
/// a breadth-first sweep over cells within the cap (exact centre-to-centre
/// distances to the seed that reached a cell first in a two-pass
/// propagation, the classic 8SSEDT approximation); empty without seeds.
fn distance_field(seeds: &[(usize, usize)], size: [usize; 2], r: f64, cap: f64) -> Vec<f32> {
    if seeds.is_empty() {
        return Vec::new();
    }
    let (w, h) = (size[0], size[1]);
    // Nearest-seed offsets propagated in two raster passes (8SSEDT).
    const FAR: i32 = 1 << 20;
    let mut off: Vec<(i32, i32)> = vec![(FAR, FAR); w * h];
    for &(x, y) in seeds {
        off[y * w + x] = (0, 0);
    }
    let d2 = |o: (i32, i32)| (o.0 as i64).pow(2) + (o.1 as i64).pow(2);
    let relax = |off: &mut Vec<(i32, i32)>, x: usize, y: usize, dx: i32, dy: i32| {
        let (nx, ny) = (x as i32 + dx, y as i32 + dy);
        if nx < 0 || ny < 0 || nx >= w as i32 || ny >= h as i32 {
            return;
        }
        let o = off[ny as usize * w + nx as usize];
        if o.0 == FAR {
            return;
        }
        let cand = (o.0 + dx, o.1 + dy);
        if d2(cand) < d2(off[y * w + x]) {
            off[y * w + x] = cand;
        }
    };
    for y in 0..h {
        for x in 0..w {
            for (dx, dy) in [(-1, 0), (0, -1), (-1, -1), (1, -1)] {
                relax(&mut off, x, y, dx, dy);
            }
        }
        for x in (0..w).rev() {
            relax(&mut off, x, y, 1, 0);
        }
    }
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            for (dx, dy) in [(1, 0), (0, 1), (1, 1), (-1, 1)] {
                relax(&mut off, x, y, dx, dy);
            }
        }
        for x in 0..w {
            relax(&mut off, x, y, -1, 0);
        }
    }
    off.into_iter()
        .map(|o| {
            if o.0 == FAR {
                cap as f32
            } else {
                ((d2(o) as f64).sqrt() * r).min(cap) as f32
            }
        })
        .collect()
}

/// One sampled pixel as the baselines see it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelObservation {
    /// Ray direction in the camera frame (unit).
    pub dir: Vector3<f64>,
    /// The pixel's class, or [`NO_LABEL`].
    pub label: u16,
    /// The camera-frame point at the pixel's depth, if it has one.
    pub point: Option<Vector3<f64>>,
}

/// Builds the observations of `pixels` from their labels and z-depths
/// (0: none); a depth beyond `max_depth` counts as none.
pub fn observations(
    intrinsics: &Intrinsics,
    pixels: &[(u32, u32)],
    labels: &[u16],
    depths: &[f32],
    max_depth: Option<f64>,
) -> Vec<PixelObservation> {
    let max = max_depth.unwrap_or(f64::INFINITY);
    pixels
        .iter()
        .zip(labels.iter().zip(depths))
        .map(|(&(u, v), (&label, &z))| PixelObservation {
            dir: intrinsics.pixel_dir(u, v),
            label,
            point: (z > 0.0 && z.is_finite() && f64::from(z) <= max)
                .then(|| intrinsics.back_project(u, v, z as f64).coords),
        })
        .collect()
}

/// How many of `observations` enter `baseline`'s likelihood, whatever
/// the pose: SeDAR\*'s pixels with a class, SIMP\*'s with a depth and a
/// class the plan has.
pub fn evidence(
    baseline: Baseline,
    observations: &[PixelObservation],
    plan: &LabelledPlan,
) -> usize {
    observations
        .iter()
        .filter(|o| enters(baseline, o, plan))
        .count()
}

/// Whether `o` enters `baseline`'s likelihood (see [`evidence`]).
fn enters(baseline: Baseline, o: &PixelObservation, plan: &LabelledPlan) -> bool {
    match baseline {
        Baseline::Sedar => o.label != NO_LABEL,
        Baseline::Simp => o.point.is_some() && plan.has_class(o.label),
    }
}

/// The tempered log-likelihood of `pose` under `baseline` for
/// `observations`; `origin` is the plan's one-layer map's grid origin (the
/// caster's frame).
pub fn log_likelihood(
    baseline: Baseline,
    pose: &Pose,
    observations: &[PixelObservation],
    plan: &LabelledPlan,
    caster: &PlanarCaster,
    origin: &Vector3<f64>,
    params: &BaselineParams,
) -> f64 {
    let mut sum = 0.0;
    let mut n = 0usize;
    let c = plan.classes().max(1) as f64;
    let mut sedar_rays: Vec<(Ray, u16)> = Vec::new();
    for o in observations {
        // A pixel without a class (SeDAR*: it would match a column without
        // one), or without a depth or of a class the plan lacks (SIMP*),
        // says nothing of the pose.
        if !enters(baseline, o, plan) {
            continue;
        }
        match baseline {
            Baseline::Sedar => {
                let w = pose.rotation * o.dir;
                let p = pose.translation.vector - origin;
                let ray = Ray::new(
                    [p.x as f32, p.y as f32, p.z as f32],
                    [w.x as f32, w.y as f32, w.z as f32],
                );
                sedar_rays.push((ray, o.label));
            }
            Baseline::Simp => {
                let Some(q) = o.point else { continue };
                let wpt = pose * nalgebra::Point3::from(q);
                let Some(d) = plan.distance(o.label, wpt.x, wpt.y, params.max_distance) else {
                    continue;
                };
                let pr = (1.0 - params.z_rand)
                    * (-d * d / (2.0 * params.sigma * params.sigma)).exp()
                    + params.z_rand;
                sum += pr.ln();
                n += 1;
            }
        }
    }
    if !sedar_rays.is_empty() {
        // One batch, so the caster casts each distinct planar ray once.
        let rays: Vec<Ray> = sedar_rays.iter().map(|r| r.0).collect();
        let mut hits = vec![crate::raycast::Hit::miss(); rays.len()];
        caster.cast_serial(&rays, &mut hits);
        for (hit, (_, label)) in hits.iter().zip(&sedar_rays) {
            let matched = hit.is_hit() && plan.leaf_label(hit.leaf) == *label;
            let pr = (1.0 - params.z_rand) * f64::from(u8::from(matched)) + params.z_rand / c;
            sum += pr.ln();
            n += 1;
        }
    }
    if n == 0 {
        return 0.0;
    }
    params.beams / n as f64 * sum
}

/// Multiplies every particle's weight by its likelihood (in log space,
/// shifted by the best so nothing underflows) and normalizes.
pub fn weigh(particles: &mut [Particle], log_l: &[f64]) {
    let best = log_l.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !best.is_finite() {
        return;
    }
    for (p, &l) in particles.iter_mut().zip(log_l) {
        p.weight *= (l - best).exp();
    }
    super::particles::normalize(particles);
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::map::key::GridSpec;
    use crate::map::{FloorPlanParams, LanguageMap};
    use nalgebra::{UnitQuaternion, Vector3};

    /// Three classes (unit axes). A 0.5 m plan: a wall of class 0 at
    /// column x 8 (x 4.0..4.5 m), y 0..=7, and a column of class 1 at
    /// (3, 7) (x 1.5..2.0, y 3.5..4.0).
    pub(crate) fn scene() -> (FloorPlan, LanguageMap, FeatureDb) {
        let classes =
            FeatureDb::from_rows(3, 0.0, vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
                .unwrap();
        let grid = GridSpec {
            resolution: 0.5,
            origin: Vector3::zeros(),
        };
        let mut leaves = vec![];
        for j in 0..8 {
            leaves.push(([8, j, 1], 0));
        }
        leaves.push(([3, 7, 1], 1));
        leaves.push(([0, 0, 0], 2)); // floor, below the band
        let map = LanguageMap::from_cells(grid, classes.clone(), "t", leaves).unwrap();
        let plan = FloorPlan::from_map(
            &map,
            &FloorPlanParams {
                band_min: 0.5,
                band_max: 1.0,
            },
        )
        .unwrap();
        let one = plan.to_language_map().unwrap();
        (plan, one, classes)
    }

    /// A camera at (x, y, 0.75) looking along world +x (camera z) with
    /// camera y down (world -z).
    pub(crate) fn camera(x: f64, y: f64) -> Pose {
        let r = nalgebra::Matrix3::new(0.0, 0.0, 1.0, -1.0, 0.0, 0.0, 0.0, -1.0, 0.0);
        let q = UnitQuaternion::from_matrix(&r);
        Pose::from_parts(nalgebra::Translation3::new(x, y, 0.75), q)
    }

    #[test]
    fn labelled_plan_and_distance_field_by_hand() {
        let (plan, one, classes) = scene();
        let lp = LabelledPlan::new(&plan, &one.cells(), one.rows(), &classes, 2.0).unwrap();
        // The floor (class 2) is outside the band: no column, no field.
        assert_eq!(lp.distance(2, 1.0, 1.0, 2.0), None);
        // Class 0 wall starts at x 4.0 (centre of column 8: 4.25). From
        // the centre of column (5, 2) (2.75, 1.25): 3 columns away, 1.5 m.
        let d = lp.distance(0, 2.75, 1.25, 2.0).unwrap();
        assert!((d - 1.5).abs() < 1e-6, "{d}");
        // Class 1 column (3, 7), from (5, 5): offsets (2, 2): 2 sqrt 2
        // cells = 1.414 m.
        let d = lp.distance(1, 2.75, 2.75, 2.0).unwrap();
        assert!((d - 2f64.sqrt()).abs() < 1e-5, "{d}");
        // Capped far away.
        assert_eq!(lp.distance(1, 2.75, 0.25, 1.0), Some(1.0));
        // Past the outer wall (column 9, outside the columns' bounds) as
        // far as inside it (column 7): 0.5 m both, not the cap; the
        // fields reach the cap past the bounds, and beyond it the cap.
        let outside = lp.distance(0, 4.75, 1.25, 2.0).unwrap();
        let inside = lp.distance(0, 3.75, 1.25, 2.0).unwrap();
        assert!(
            (outside - 0.5).abs() < 1e-6 && (inside - 0.5).abs() < 1e-6,
            "{outside} {inside}"
        );
        assert!((lp.distance(0, 5.75, 1.25, 2.0).unwrap() - 1.5).abs() < 1e-6);
        assert_eq!(lp.distance(0, 7.0, 1.25, 2.0), Some(2.0));
        assert_eq!(lp.lo(), [3 - 4, -4]);
        // A cap that is not a positive distance, or fields past the plan
        // cells' limit: refused by name.
        let cap = |d: f64| {
            LabelledPlan::new(&plan, &one.cells(), one.rows(), &classes, d)
                .err()
                .map(|e| e.to_string())
        };
        for d in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(cap(d).unwrap().contains("baseline max distance"), "{d}");
        }
        let far = cap(1e5).unwrap();
        assert!(far.contains("400006 x 400008 cells of 0.5 m"), "{far}");
        assert_eq!(cap(100.0), None);
    }

    /// Each baseline's likelihood prefers the true pose: pixels straight
    /// ahead that see the class-0 wall 2 m away (SeDAR* label, SIMP*
    /// label + depth) score higher at the true pose than 0.5 m to the side
    /// (SIMP*, depth then misplaces the points) or turned towards the
    /// class-1 column (SeDAR*).
    #[test]
    fn baselines_prefer_the_true_pose() {
        let (plan, one, classes) = scene();
        let lp = LabelledPlan::new(&plan, &one.cells(), one.rows(), &classes, 2.0).unwrap();
        let caster = PlanarCaster::new(0.5, &one.cells());
        let k = Intrinsics::from_hfov(64, 48, 90.0);
        let pixels: Vec<(u32, u32)> = (28..36).map(|u| (u, 24)).collect();
        let truth = camera(2.0, 1.0);
        // Every pixel sees the wall (class 0) at z-depth 2.0.
        let obs = observations(&k, &pixels, &[0; 8], &[2.0; 8], None);
        let origin = one.grid().origin;
        let p = BaselineParams::default();
        let l = |b: Baseline, pose: &Pose| log_likelihood(b, pose, &obs, &lp, &caster, &origin, &p);
        // SIMP*: at the truth every point lands on x = 4.0 .. (wall face),
        // inside the wall's first column: d = 0 and p = 1 (log 0).
        assert!(l(Baseline::Simp, &truth).abs() < 1e-9);
        let behind = camera(1.5, 1.0);
        let expected =
            p.beams * ((1.0 - p.z_rand) * (-0.25f64 / (2.0 * 0.04)).exp() + p.z_rand).ln();
        assert!((l(Baseline::Simp, &behind) - expected).abs() < 1e-6);
        assert!(l(Baseline::Simp, &truth) > l(Baseline::Simp, &behind));
        // SeDAR*: every ray from the truth reaches the wall: p = 0.9 + 0.1/3.
        let hit = p.beams * (0.9f64 + 0.1 / 3.0).ln();
        assert!((l(Baseline::Sedar, &truth) - hit).abs() < 1e-9);
        // Turned 90 degrees left (towards +y): the rays reach the class-1
        // column or nothing: every label mismatches.
        let turned = Pose::from_parts(
            truth.translation,
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 90f64.to_radians())
                * truth.rotation,
        );
        let miss = p.beams * (0.1f64 / 3.0).ln();
        assert!((l(Baseline::Sedar, &turned) - miss).abs() < 1e-9);
        // SeDAR*: pixels without a class add nothing (nor match a column
        // without one); evidence counts the pixels that enter.
        let void = observations(&k, &pixels, &[NO_LABEL; 8], &[2.0; 8], None);
        assert_eq!(l(Baseline::Sedar, &truth), {
            let mixed: Vec<_> = obs.iter().chain(&void).copied().collect();
            log_likelihood(Baseline::Sedar, &truth, &mixed, &lp, &caster, &origin, &p)
        });
        assert_eq!(evidence(Baseline::Sedar, &void, &lp), 0);
        assert_eq!(evidence(Baseline::Sedar, &obs, &lp), 8);
        assert_eq!(evidence(Baseline::Simp, &obs, &lp), 8);
        assert_eq!(evidence(Baseline::Simp, &void, &lp), 0);
        // Pixels without depth or of a class the plan lacks add nothing.
        let none = observations(&k, &pixels, &[2; 8], &[0.0; 8], None);
        assert_eq!(
            log_likelihood(Baseline::Simp, &truth, &none, &lp, &caster, &origin, &p),
            0.0
        );
        // Weighing: the better particle gets the larger weight.
        let mut ps = vec![Particle::new(truth, 0.5), Particle::new(behind, 0.5)];
        weigh(
            &mut ps,
            &[l(Baseline::Simp, &truth), l(Baseline::Simp, &behind)],
        );
        assert!(ps[0].weight > ps[1].weight && (ps[0].weight + ps[1].weight - 1.0).abs() < 1e-12);
    }
}
