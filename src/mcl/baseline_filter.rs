//! The baselines' filter loop: SeDAR\* or SIMP\* ([`super::baselines`])
//! as the sensor model behind the same stages as OMCL's filter (planar
//! motion, stratified pixel sampling on the plan's database, estimate,
//! resampling policy), one frame at a time, so that `omcl bench table1`'s
//! 2-D block and `omcl localize --floorplan --baseline` run the same code.

use std::sync::Arc;
use std::time::Instant;

use nalgebra::Vector3;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use super::MclError;
use super::baselines::{self, Baseline, BaselineParams, LabelledPlan, NO_LABEL, PixelObservation};
use super::estimate::estimate;
use super::filter::{FilterConfig, StepReport, StepTimings, check_frame_size};
use super::motion::{MotionMode, MotionModel, check_pose};
use super::particles::{Particle, ess, normalize};
use super::recovery::{Recovery, RecoveryParams};
use super::resample::resample;
use super::sampling::{SamplingParams, sample_pixels};
use crate::frame::FrameFeatures;
use crate::geometry::{Intrinsics, Pose};
use crate::map::{FeatureDb, FloorPlan, LanguageMap};
use crate::raycast::{PlanarCaster, RayCaster};

/// The common floor plan as the baselines read it: its columns labelled by
/// the nearest class, the per-class distance fields, its planar caster,
/// and the database the frame's pixels are sampled on.
#[derive(Debug, Clone)]
pub struct BaselinePlan {
    labelled: LabelledPlan,
    caster: Arc<PlanarCaster>,
    /// The one-layer map's grid origin (the caster's frame).
    origin: Vector3<f64>,
    /// The plan's feature rows (the pixels' stratification).
    db: FeatureDb,
    classes: FeatureDb,
}

/// [`MclError::BadParam`]'s name when the class table is refused (none,
/// or more than the labels hold): the caller's table to change.
pub const CLASSES_PARAM: &str = "baseline classes";

impl BaselinePlan {
    /// `plan`, its one-layer map `map` and that map's caster `caster`
    /// (columns as prisms, leaves in `map`'s order), labelled with
    /// `classes` (one row per class, the frames' feature space). Fails when
    /// the classes' dimension is not the plan's or there are none.
    pub fn new(
        plan: &FloorPlan,
        map: &LanguageMap,
        caster: Arc<PlanarCaster>,
        classes: FeatureDb,
        params: &BaselineParams,
    ) -> Result<Self, MclError> {
        if classes.is_empty() {
            return Err(MclError::BadParam {
                name: CLASSES_PARAM,
                why: "the class table has no classes: SeDAR* and SIMP* label the plan and the \
                      pixels by class"
                    .into(),
            });
        }
        if classes.len() > usize::from(NO_LABEL) {
            return Err(MclError::BadParam {
                name: CLASSES_PARAM,
                why: format!(
                    "{} classes: SeDAR* and SIMP* label with at most {NO_LABEL}",
                    classes.len()
                ),
            });
        }
        if classes.dim() != map.db().dim() {
            return Err(MclError::DimMismatch {
                expected: map.db().dim(),
                got: classes.dim(),
            });
        }
        if caster.len() != map.rows().len() {
            return Err(MclError::CasterMismatch {
                caster: caster.len(),
                map: map.rows().len(),
            });
        }
        let cells = map.cells();
        let labelled = LabelledPlan::new(plan, &cells, map.rows(), &classes, params.max_distance)?;
        Ok(BaselinePlan {
            labelled,
            caster,
            origin: map.grid().origin,
            db: map.db().clone(),
            classes,
        })
    }

    /// The plan's columns and distance fields by class.
    pub fn labelled(&self) -> &LabelledPlan {
        &self.labelled
    }

    /// The classes' count.
    pub fn classes(&self) -> usize {
        self.classes.len()
    }
}

/// A particle filter with a baseline's sensor model.
pub struct BaselineFilter {
    baseline: Baseline,
    params: BaselineParams,
    plan: Arc<BaselinePlan>,
    intrinsics: Intrinsics,
    motion: MotionModel,
    sampling: SamplingParams,
    config: FilterConfig,
    particles: Vec<Particle>,
    rng: ChaCha8Rng,
    recovery: Recovery,
}

impl BaselineFilter {
    /// A filter of `baseline` on `plan` from `particles`, drawing from
    /// `rng`: `config`'s motion noise (always planar: the plan's poses are
    /// x, y and yaw), sampling (with [`BaselineParams::pixels`] pixels),
    /// estimate and resampling policy; its sensor, sharpening, layers,
    /// adaptive count and recovery are OMCL's and not used.
    pub fn new(
        baseline: Baseline,
        params: BaselineParams,
        plan: Arc<BaselinePlan>,
        intrinsics: Intrinsics,
        config: FilterConfig,
        particles: Vec<Particle>,
        rng: ChaCha8Rng,
    ) -> Result<Self, MclError> {
        config.validate()?;
        if particles.is_empty() {
            return Err(MclError::NoParticles);
        }
        if params.pixels == 0 {
            return Err(MclError::BadParam {
                name: "baseline pixels",
                why: "must be at least 1".into(),
            });
        }
        if let Some(m) = params.max_depth.filter(|m| !(m.is_finite() && *m > 0.0)) {
            return Err(MclError::BadParam {
                name: "baseline max depth",
                why: format!("{m} m: must be a positive number of metres"),
            });
        }
        let mut particles = particles;
        normalize(&mut particles);
        Ok(BaselineFilter {
            baseline,
            params,
            plan,
            intrinsics,
            motion: MotionModel {
                mode: MotionMode::Planar,
                ..config.motion
            },
            sampling: SamplingParams {
                rays: params.pixels,
                ..config.sampling
            },
            config,
            particles,
            rng,
            recovery: Recovery::default(),
        })
    }

    /// The particles (normalized weights).
    pub fn particles(&self) -> &[Particle] {
        &self.particles
    }

    /// Which baseline this is.
    pub fn baseline(&self) -> Baseline {
        self.baseline
    }

    /// The camera the frames must match.
    pub fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }

    /// Replaces the particles with `n` drawn about `pose` (the local
    /// start: `sigma_m` on the ground plane, `sigma_rad` on yaw), from
    /// the filter's own generator, and forgets the confidence's history.
    pub fn reinitialize(
        &mut self,
        pose: &Pose,
        n: usize,
        sigma_m: f64,
        sigma_rad: f64,
    ) -> Result<(), MclError> {
        if n == 0 {
            return Err(MclError::NoParticles);
        }
        self.particles = super::local_init(pose, n, sigma_m, sigma_rad, &mut self.rng);
        normalize(&mut self.particles);
        self.recovery = Recovery::default();
        Ok(())
    }

    /// One step: the motion by `increment` (`None`: the first frame, no
    /// motion yet), the frame's pixels sampled, labelled by their nearest
    /// class and, for SIMP\*, placed at `depth` (`width * height`
    /// z-depths in metres, row-major, 0 where there is none; SIMP\*
    /// skips pixels without, and refuses a frame without depth), every
    /// particle weighed, the estimate taken and the set resampled when due.
    /// A frame refused for its size, dimension or depth changes nothing
    /// (particles and generator). The report's mean likelihood is the mean over particles
    /// of the geometric mean of the pixels' likelihoods.
    pub fn step(
        &mut self,
        increment: Option<&Pose>,
        frame: &dyn FrameFeatures,
        depth: Option<&[f32]>,
    ) -> Result<StepReport, MclError> {
        let k = self.intrinsics;
        check_frame_size(&k, frame)?;
        // Before any draw, so a refused frame leaves the generator as it was.
        if frame.dim() != self.plan.db.dim() {
            return Err(MclError::DimMismatch {
                expected: self.plan.db.dim(),
                got: frame.dim(),
            });
        }
        if self.baseline == Baseline::Simp && depth.is_none() {
            return Err(MclError::BadParam {
                name: "depth image",
                why: "SIMP* places each pixel at its depth, and the frame has none".into(),
            });
        }
        if let Some(d) = depth
            && d.len() != (k.width as usize) * (k.height as usize)
        {
            return Err(MclError::BadParam {
                name: "depth image",
                why: format!("{} depths for a {} x {} camera", d.len(), k.width, k.height),
            });
        }
        if let Some(inc) = increment {
            check_pose(inc)?;
        }
        let t0 = Instant::now();
        let mut moved = self.particles.clone();
        if let Some(inc) = increment {
            self.motion.predict(&mut moved, inc, &mut self.rng)?;
        }
        let t1 = Instant::now();
        let pixels = sample_pixels(frame, &self.plan.db, &self.sampling, &mut self.rng)?;
        let obs = observe(
            frame,
            depth,
            &pixels,
            &self.plan.classes,
            &k,
            self.params.max_depth,
        )?;
        let t2 = Instant::now();
        let plan = &self.plan;
        let (baseline, params) = (self.baseline, &self.params);
        let log_l: Vec<f64> = moved
            .par_iter()
            .map(|p| {
                baselines::log_likelihood(
                    baseline,
                    &p.pose,
                    &obs,
                    &plan.labelled,
                    &plan.caster,
                    &plan.origin,
                    params,
                )
            })
            .collect();
        baselines::weigh(&mut moved, &log_l);
        let t3 = Instant::now();
        let est = estimate(&moved, &self.config.estimate).ok_or(MclError::NoParticles)?;
        let ess_now = ess(&moved);
        let beams = self.params.beams.max(f64::MIN_POSITIVE);
        let mean_l =
            log_l.iter().map(|l| (l / beams).exp()).sum::<f64>() / log_l.len().max(1) as f64;
        // A frame none of whose pixels enters the likelihood (SIMP*: no
        // depth, say a sensor's first frames) weighs every particle alike
        // and says nothing of the confidence.
        if baselines::evidence(baseline, &obs, &plan.labelled) > 0 {
            self.recovery.update(mean_l, &RecoveryParams::default());
        }
        let resampled = self.config.resample.due(&moved);
        if resampled {
            let n = moved.len();
            resample(
                &mut moved,
                n,
                self.config.resample.reset_weights,
                &mut self.rng,
            );
        }
        self.particles = moved;
        let t4 = Instant::now();
        Ok(StepReport {
            estimate: est.pose,
            ess: ess_now,
            spread: est.spread,
            mean_likelihood: mean_l,
            confidence: self.recovery.confidence(),
            n_particles: self.particles.len(),
            n_rays: pixels.len(),
            resampled,
            injected: 0,
            timings: StepTimings {
                predict: t1 - t0,
                features: t2 - t1,
                weigh: t3 - t2,
                cast: std::time::Duration::ZERO,
                update: t4 - t3,
            },
        })
    }
}

/// The baselines' observations of the sampled pixels: each pixel's
/// direction, nearest class and depth (`depth`: `width * height`
/// z-depths, metres, 0 none; one beyond `max_depth` counts as none).
pub fn observe(
    f: &dyn FrameFeatures,
    depth: Option<&[f32]>,
    pixels: &[(u32, u32)],
    classes: &FeatureDb,
    k: &Intrinsics,
    max_depth: Option<f64>,
) -> Result<Vec<PixelObservation>, MclError> {
    if f.dim() != classes.dim() {
        return Err(MclError::DimMismatch {
            expected: classes.dim(),
            got: f.dim(),
        });
    }
    let mut buf = vec![0.0f32; classes.dim()];
    let mut labels = Vec::with_capacity(pixels.len());
    let mut depths = Vec::with_capacity(pixels.len());
    for &(u, v) in pixels {
        f.feature(u, v, &mut buf);
        labels.push(
            classes
                .nearest(&buf)
                .map_err(|e| MclError::BadParam {
                    name: "pixel feature",
                    why: e.to_string(),
                })?
                .map_or(NO_LABEL, |(c, _)| c as u16),
        );
        depths.push(depth.map_or(0.0, |d| d[(v * f.width() + u) as usize]));
    }
    Ok(baselines::observations(
        k, pixels, &labels, &depths, max_depth,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::DenseFeatures;
    use crate::mcl::baselines::tests::{camera, scene};
    use rand::SeedableRng;

    /// The scene of [`super::super::baselines`]'s tests (a class-0 wall at
    /// x 4.0 m, a class-1 column) with its planar caster.
    fn plan() -> BaselinePlan {
        let (plan, one, classes) = scene();
        let caster = Arc::new(PlanarCaster::new(0.5, &one.cells()));
        BaselinePlan::new(&plan, &one, caster, classes, &BaselineParams::default()).unwrap()
    }

    /// A 64 x 48 frame of one class (its unit axis in 3 dimensions).
    fn frame(class: usize) -> DenseFeatures {
        let mut f = [0.0f32; 3];
        f[class] = 1.0;
        DenseFeatures {
            width: 64,
            height: 48,
            dim: 3,
            data: f.repeat(64 * 48),
        }
    }

    fn filter(baseline: Baseline, start: &Pose, sigma_m: f64) -> BaselineFilter {
        with_params(baseline, start, sigma_m, BaselineParams::default()).unwrap()
    }

    fn with_params(
        baseline: Baseline,
        start: &Pose,
        sigma_m: f64,
        params: BaselineParams,
    ) -> Result<BaselineFilter, MclError> {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let ps = crate::mcl::local_init(start, 256, sigma_m, 0.0, &mut rng);
        let config = FilterConfig {
            sampling: SamplingParams {
                boundary_margin: Some(0),
                ..SamplingParams::default()
            },
            ..FilterConfig::floor_plan()
        };
        BaselineFilter::new(
            baseline,
            params,
            Arc::new(plan()),
            Intrinsics::from_hfov(64, 48, 90.0),
            config,
            ps,
            rng,
        )
    }

    /// SIMP*: every pixel sees the wall at 2 m, whose column spans x 4.0
    /// to 4.5 m, so every camera with x in 2.0 to 2.5 places the points
    /// inside it (distance 0). From a cloud spread 0.4 m about x 1.5 (0.5
    /// m short of that band) the estimate's x comes into it (y is free
    /// along a straight wall). The first frame moves nothing: the
    /// particles after it are the start's.
    #[test]
    fn simp_pulls_the_estimate_to_the_wall_distance() {
        let mut f = filter(Baseline::Simp, &camera(1.5, 1.0), 0.4);
        let before: Vec<Pose> = f.particles().iter().map(|p| p.pose).collect();
        let mean_x = before.iter().map(|p| p.translation.x).sum::<f64>() / 256.0;
        assert!((mean_x - 1.5).abs() < 0.1, "{mean_x}");
        let depth = vec![2.0f32; 64 * 48];
        let r = f.step(None, &frame(0), Some(&depth)).unwrap();
        let x = r.estimate.translation.x;
        assert!(
            (1.95..2.55).contains(&x),
            "estimate x {x:.3}, cloud's mean {mean_x:.3}"
        );
        assert!(r.ess < 128.0, "ESS {}", r.ess);
        // Without motion, every particle after the step is one of the start's.
        for p in f.particles() {
            assert!(
                before
                    .iter()
                    .any(|q| (q.translation.vector - p.pose.translation.vector).norm() < 1e-12)
            );
        }
        assert!(r.mean_likelihood > 0.0 && r.mean_likelihood <= 1.0);
    }

    /// SIMP*'s depth range: every pixel at z-depth 2 m, so a range of 2 m
    /// keeps them all (the estimate pulled to the wall distance, as
    /// without a range) and one of 1.99 m none: every particle weighs the
    /// same, and nothing pulls the estimate.
    /// Ranges that are no positive number are refused by name.
    #[test]
    fn simp_places_no_pixel_beyond_its_depth_range() {
        let start = camera(1.5, 1.0);
        let depth = vec![2.0f32; 64 * 48];
        let run = |max_depth: Option<f64>| {
            let params = BaselineParams {
                max_depth,
                ..BaselineParams::default()
            };
            let mut f = with_params(Baseline::Simp, &start, 0.4, params).unwrap();
            let r = f.step(None, &frame(0), Some(&depth)).unwrap();
            (r, f.particles().to_vec())
        };
        let (all, _) = run(None);
        let (kept, _) = run(Some(2.0));
        assert_eq!(kept.estimate, all.estimate);
        assert!((1.95..2.55).contains(&kept.estimate.translation.x));
        let (none, particles) = run(Some(1.99));
        assert!((none.ess - 256.0).abs() < 1e-6, "ESS {}", none.ess);
        assert!(
            particles
                .iter()
                .all(|p| (p.weight - 1.0 / 256.0).abs() < 1e-12)
        );
        assert!(none.estimate.translation.x < 1.95, "{:?}", none.estimate);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let params = BaselineParams {
                max_depth: Some(bad),
                ..BaselineParams::default()
            };
            let e = with_params(Baseline::Simp, &start, 0.4, params)
                .err()
                .unwrap();
            assert!(e.to_string().contains("baseline max depth"), "{bad}: {e}");
        }
    }

    /// A SIMP* frame without depth anywhere (a sensor's first frames)
    /// weighs every particle alike and leaves the confidence as it was.
    #[test]
    fn a_frame_without_evidence_leaves_the_confidence() {
        // A frame that fits, then class 1 at the wall's distance (the
        // class-1 column is elsewhere): the likelihood drops, and with it
        // the confidence.
        let truth = camera(2.0, 1.0);
        let mut f = filter(Baseline::Simp, &truth, 0.3);
        let depth = vec![2.0f32; 64 * 48];
        f.step(None, &frame(0), Some(&depth)).unwrap();
        let first = f.step(None, &frame(1), Some(&depth)).unwrap();
        assert!(first.confidence < 0.9, "{}", first.confidence);
        let blank = f.step(None, &frame(1), Some(&[0.0; 64 * 48])).unwrap();
        assert_eq!(blank.confidence, first.confidence);
        assert!((blank.ess - first.ess).abs() < 1e-9 || first.resampled);
    }

    /// SeDAR*: a frame all of class 0 (the wall) seen from the truth
    /// facing it agrees; turned to face +y the rays reach the class-1
    /// column or nothing, so a cloud with half its particles turned keeps
    /// the ones facing the wall.
    #[test]
    fn sedar_keeps_the_particles_that_see_the_frames_labels() {
        let truth = camera(2.0, 1.0);
        let turned = Pose::from_parts(
            truth.translation,
            nalgebra::UnitQuaternion::from_axis_angle(
                &nalgebra::Vector3::z_axis(),
                90f64.to_radians(),
            ) * truth.rotation,
        );
        let mut f = filter(Baseline::Sedar, &truth, 0.0);
        let ps: Vec<Particle> = (0..256)
            .map(|i| Particle::new(if i % 2 == 0 { truth } else { turned }, 1.0))
            .collect();
        f.particles = ps;
        normalize(&mut f.particles);
        let r = f.step(None, &frame(0), None).unwrap();
        let angle = r.estimate.rotation.angle_to(&truth.rotation).to_degrees();
        assert!(angle < 1.0, "estimate {angle:.2} degrees from the truth");
    }

    /// A frame of another size, depths of another count or features of
    /// another dimension are refused and leave the particles as they were;
    /// classes of another dimension than the plan's are refused by name.
    #[test]
    fn bad_frames_and_classes_are_refused_and_change_nothing() {
        let truth = camera(2.0, 1.0);
        let mut f = filter(Baseline::Simp, &truth, 0.3);
        let before: Vec<Particle> = f.particles().to_vec();
        let step = Pose::translation(0.1, 0.0, 0.0);
        let small = DenseFeatures {
            width: 32,
            ..frame(0)
        };
        assert!(matches!(
            f.step(Some(&step), &small, None),
            Err(MclError::ImageSize { got_w: 32, .. })
        ));
        let e = f
            .step(Some(&step), &frame(0), Some(&[2.0; 10]))
            .unwrap_err();
        assert!(
            e.to_string().contains("10 depths for a 64 x 48 camera"),
            "{e}"
        );
        let wide = DenseFeatures {
            dim: 4,
            data: vec![0.5; 64 * 48 * 4],
            ..frame(0)
        };
        assert!(matches!(
            f.step(Some(&step), &wide, None),
            Err(MclError::DimMismatch { got: 4, .. })
        ));
        let e = f.step(Some(&step), &frame(0), None).unwrap_err();
        assert!(e.to_string().contains("has none"), "{e}");
        assert_eq!(f.particles(), &before[..]);
        // Nor the generator: a good frame after the refused ones gives what
        // it gives to a filter that never saw them.
        let depth = vec![2.0f32; 64 * 48];
        let mut fresh = filter(Baseline::Simp, &truth, 0.3);
        let a = f.step(Some(&step), &frame(0), Some(&depth)).unwrap();
        let b = fresh.step(Some(&step), &frame(0), Some(&depth)).unwrap();
        assert_eq!(a.estimate, b.estimate);
        assert_eq!(f.particles(), fresh.particles());

        let (plan, one, _) = scene();
        let caster = Arc::new(PlanarCaster::new(0.5, &one.cells()));
        let four = FeatureDb::from_rows(4, 0.0, vec![1.0, 0.0, 0.0, 0.0]).unwrap();
        let e =
            BaselinePlan::new(&plan, &one, caster, four, &BaselineParams::default()).unwrap_err();
        assert!(
            matches!(
                e,
                MclError::DimMismatch {
                    expected: 3,
                    got: 4
                }
            ),
            "{e}"
        );
    }
}
