//! A camera tracked on a floor plan by one of Table I's baselines, SeDAR\*
//! or SIMP\* ([`crate::mcl::baselines`]), with the session's conventions:
//! odometry poses in, level pose reports out. `omcl localize --floorplan
//! --baseline` runs it on a recorded sequence.
//!
//! Like a floor plan's OMCL session ([`super::SharedMap::floor_plan`]) it
//! holds the camera level at the start's height: the start pose is
//! levelled ([`super::ground::level`]) and so is every odometry pose, so the
//! odometry's horizontal motion and heading move the particles. It starts
//! from a pose only, as both baselines do in the paper (the local start);
//! their sensors score labels, not the floor's feature that global and
//! prompt starts place cameras with.

use std::sync::{Arc, Mutex};

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

use super::floorplan::PlanScene;
use super::ground::{self, Mount};
use super::{MAX_ODOMETRY_STEP_M, PoseReport, SessionConfig, SessionError, Start};
use crate::frame::FrameFeatures;
use crate::geometry::Pose;
use crate::io::labels::EmbeddingTable;
use crate::map::FeatureDb;
use crate::map::{FloorPlan, LanguageMap};
use crate::mcl::baseline_filter::{BaselineFilter, BaselinePlan, CLASSES_PARAM};
use crate::mcl::baselines::{Baseline, BaselineParams};
use crate::mcl::{self, MclError, Particle};
use crate::raycast::PlanarCaster;

/// What the baselines localize on: a floor plan, the plan as a one-layer
/// map and its columns as infinitely tall prisms ([`PlanScene`]'s `plan`,
/// `map` and `caster`; a floor-plan [`super::SharedMap`] keeps them for
/// its baseline sessions).
pub struct BaselineMap {
    pub plan: FloorPlan,
    pub map: LanguageMap,
    pub caster: Arc<PlanarCaster>,
    /// The plan labelled by each class table its sessions used (with the
    /// likelihood field's cap): built once and shared, since its per-class
    /// distance fields cover the plan (a server's sessions on one map
    /// would each hold a copy otherwise).
    labelled: Mutex<Vec<(LabelKey, Arc<BaselinePlan>)>>,
}

/// What a [`BaselinePlan`] is built from besides the map: the class rows
/// (dimension and values, bit for bit) and the distance cap's bits.
#[derive(PartialEq)]
struct LabelKey {
    dim: usize,
    rows: Vec<u32>,
    max_distance: u64,
}

impl BaselineMap {
    /// A baseline map of `plan`, its one-layer map `map` and `map`'s
    /// caster of infinitely tall prisms.
    pub fn new(plan: FloorPlan, map: LanguageMap, caster: Arc<PlanarCaster>) -> Self {
        BaselineMap {
            plan,
            map,
            caster,
            labelled: Mutex::new(Vec::new()),
        }
    }

    /// The plan labelled with `classes` for `params` (built on the first
    /// call for those classes and that cap, then shared).
    fn labelled(
        &self,
        classes: &EmbeddingTable,
        params: &BaselineParams,
    ) -> Result<Arc<BaselinePlan>, SessionError> {
        let key = LabelKey {
            dim: classes.dim,
            rows: classes.data.iter().map(|x| x.to_bits()).collect(),
            max_distance: params.max_distance.to_bits(),
        };
        // A poisoned lock only means a build panicked: the list is whole.
        let mut cache = self.labelled.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, plan)) = cache.iter().find(|(k, _)| *k == key) {
            return Ok(plan.clone());
        }
        let db = FeatureDb::from_rows(classes.dim, 0.0, classes.data.clone())
            .map_err(|e| SessionError::ClassTable(e.to_string()))?;
        // What the class table is refused for (none, too many, another
        // dimension) is the caller's to change, not a fault of the filter.
        let plan = Arc::new(
            BaselinePlan::new(&self.plan, &self.map, self.caster.clone(), db, params).map_err(
                |e| match e {
                    MclError::BadParam {
                        name: CLASSES_PARAM,
                        ..
                    }
                    | MclError::DimMismatch { .. } => SessionError::ClassTable(e.to_string()),
                    MclError::BadParam { .. } => SessionError::Init(e),
                    e => SessionError::Filter(e),
                },
            )?,
        );
        cache.push((key, plan.clone()));
        Ok(plan)
    }
}

impl From<PlanScene> for BaselineMap {
    fn from(scene: PlanScene) -> Self {
        BaselineMap::new(scene.plan, scene.map, scene.caster)
    }
}

/// One camera tracked by a baseline on a floor plan.
pub struct BaselineSession {
    filter: BaselineFilter,
    /// Particles at the start and after each reinitialization.
    particles: usize,
    mount: Mount,
    last_odom: Option<Pose>,
    frames: u64,
}

impl BaselineSession {
    /// `baseline` on `scene`'s plan (its one-layer map and caster), the
    /// plan's columns and the frames' pixels labelled with `classes`, from
    /// `start` (a pose: Gaussian about it, levelled), with `config`'s
    /// camera, particle count and filter (motion noise, sampling, estimate,
    /// resampling; `config.filter.seed` seeds every draw).
    pub fn new(
        scene: &BaselineMap,
        classes: &EmbeddingTable,
        baseline: Baseline,
        params: BaselineParams,
        config: &SessionConfig,
        start: &Start,
    ) -> Result<Self, SessionError> {
        let (level, sigma_m, sigma_rad) = pose_start(baseline, start)?;
        if config.particles == 0 {
            return Err(SessionError::Init(MclError::NoParticles));
        }
        if classes.dim != scene.map.db().dim() {
            return Err(SessionError::ClassTable(format!(
                "{}-d class embeddings, the floor plan's features are {}-d: {} labels the plan's \
                 columns and the pixels with the classes nearest to their features",
                classes.dim,
                scene.map.db().dim(),
                baseline.label()
            )));
        }
        let plan = scene.labelled(classes, &params)?;
        let mut rng = ChaCha8Rng::seed_from_u64(config.filter.seed);
        let particles: Vec<Particle> =
            mcl::local_init(&level, config.particles, sigma_m, sigma_rad, &mut rng);
        let filter = BaselineFilter::new(
            baseline,
            params,
            plan,
            config.intrinsics,
            config.filter,
            particles,
            rng,
        )?;
        Ok(BaselineSession {
            filter,
            particles: config.particles,
            mount: Mount::level(),
            last_odom: None,
            frames: 0,
        })
    }

    /// Replaces the particles about `start`'s pose (levelled), as many as
    /// the session started with; the next frame's odometry is the new
    /// reference (it moves nothing). Only a pose start: global and prompt
    /// starts are refused, and the session is left as it was.
    pub fn reinitialize(&mut self, start: &Start) -> Result<(), SessionError> {
        let (level, sigma_m, sigma_rad) = pose_start(self.filter.baseline(), start)?;
        self.filter
            .reinitialize(&level, self.particles, sigma_m, sigma_rad)
            .map_err(SessionError::Init)?;
        self.last_odom = None;
        Ok(())
    }

    /// The camera the frames must match.
    pub fn intrinsics(&self) -> crate::geometry::Intrinsics {
        self.filter.intrinsics()
    }

    /// Which baseline tracks the camera.
    pub fn baseline(&self) -> Baseline {
        self.filter.baseline()
    }

    /// The particles (normalized weights).
    pub fn particles(&self) -> &[Particle] {
        self.filter.particles()
    }

    /// Frames stepped so far.
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// One frame: `odom` the odometry pose of its camera
    /// (`odom_from_camera`), `stamp` its time, `depth` its z-depths
    /// (`width * height`, metres, 0 none; SIMP\* places the pixels with
    /// them and skips pixels without). A rejected frame leaves the
    /// session as it was.
    pub fn step(
        &mut self,
        odom: &Pose,
        stamp: f64,
        frame: &dyn FrameFeatures,
        depth: Option<&[f32]>,
    ) -> Result<PoseReport, SessionError> {
        super::check_input(odom, stamp)?;
        let odom = self.mount.hold(odom);
        let increment = self.last_odom.map(|prev| prev.inverse() * odom);
        if let Some(inc) = &increment {
            let moved = inc.translation.vector.norm();
            if moved > MAX_ODOMETRY_STEP_M {
                return Err(SessionError::OdometryJump(moved));
            }
        }
        let step = self
            .filter
            .step(increment.as_ref(), frame, depth)
            .map_err(|e| match e {
                // The frame's depth (SIMP*: missing, or of another size).
                MclError::BadParam { .. } => SessionError::BadFrame(e.to_string()),
                e => super::step_error(e),
            })?;
        self.last_odom = Some(odom);
        self.frames += 1;
        Ok(PoseReport::of(
            stamp,
            self.frames,
            step,
            self.filter.particles(),
        ))
    }
}

/// `start`'s pose levelled at its own height, and its spreads; refused
/// by `baseline`'s name unless it is a pose start with a valid pose and
/// finite, non-negative spreads.
fn pose_start(baseline: Baseline, start: &Start) -> Result<(Pose, f64, f64), SessionError> {
    let Start::Pose {
        pose,
        sigma_m,
        sigma_rad,
    } = start
    else {
        return Err(SessionError::BaselineStart(baseline.label()));
    };
    mcl::motion::check_pose(pose).map_err(SessionError::Init)?;
    if !(sigma_m.is_finite() && *sigma_m >= 0.0 && sigma_rad.is_finite() && *sigma_rad >= 0.0) {
        return Err(SessionError::Init(MclError::BadParam {
            name: "initial spread",
            why: format!("must be finite and >= 0, got {sigma_m} m, {sigma_rad} rad"),
        }));
    }
    Ok((
        ground::level(pose, pose.translation.vector.z),
        *sigma_m,
        *sigma_rad,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::DenseFeatures;
    use crate::geometry::Intrinsics;
    use crate::mcl::baselines::tests::{camera, scene};
    use crate::mcl::{FilterConfig, FloorParams, SamplingParams};
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// The baselines' test scene (a class-0 wall at x 4.0 to 4.5 m, a
    /// class-1 column) as a plan scene, and its three classes' table.
    fn plan_scene() -> (BaselineMap, EmbeddingTable) {
        let (plan, _, classes) = scene();
        let table = EmbeddingTable::new(
            vec![0, 1, 2],
            vec!["wall".into(), "column".into(), "floor".into()],
            3,
            classes.rows().to_vec(),
        )
        .unwrap();
        (PlanScene::from_plan(plan).unwrap().into(), table)
    }

    fn config() -> SessionConfig {
        SessionConfig {
            intrinsics: Intrinsics::from_hfov(64, 48, 90.0),
            particles: 256,
            filter: FilterConfig {
                sampling: SamplingParams {
                    boundary_margin: Some(0),
                    ..SamplingParams::default()
                },
                seed: 5,
                ..FilterConfig::floor_plan()
            },
            floor: FloorParams::default(),
            floor_feature: None,
            ground: true,
        }
    }

    /// A 64 x 48 frame of one class, or of `dim` zeros-but-one values.
    fn frame(class: usize, dim: usize) -> DenseFeatures {
        let mut f = vec![0.0f32; dim];
        f[class] = 1.0;
        DenseFeatures {
            width: 64,
            height: 48,
            dim,
            data: f.repeat(64 * 48),
        }
    }

    fn start(pose: Pose) -> Start {
        Start::Pose {
            pose,
            sigma_m: 0.4,
            sigma_rad: 0.0,
        }
    }

    /// Sessions on one map share its labelled plan (the per-class
    /// distance fields are built once); another class table or cap gets
    /// its own, and both give the same sessions.
    #[test]
    fn sessions_share_the_labelled_plan() {
        let (scene, table) = plan_scene();
        let p = BaselineParams::default();
        let a = scene.labelled(&table, &p).unwrap();
        let b = scene.labelled(&table, &p).unwrap();
        assert!(Arc::ptr_eq(&a, &b));
        let wider = BaselineParams {
            max_distance: 3.0,
            ..p
        };
        assert!(!Arc::ptr_eq(&a, &scene.labelled(&table, &wider).unwrap()));
        let mut other = table.clone();
        other.data[0] = 0.5;
        assert!(!Arc::ptr_eq(&a, &scene.labelled(&other, &p).unwrap()));
        assert_eq!(scene.labelled.lock().unwrap().len(), 3);
    }

    /// SIMP\* behind the session: a start pitched 10 degrees is levelled,
    /// every pixel seeing the wall at 2 m pulls the estimate into x 2.0 to
    /// 2.5 m, odometry 0.5 m forward (pitched too) moves it on with the
    /// wall at 1.5 m; a frame of another dimension and an odometry jump
    /// are rejected and leave the session as it was.
    #[test]
    fn simp_session_tracks_level_and_rejects_bad_frames() {
        let (scene, table) = plan_scene();
        let pitch = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 10f64.to_radians());
        let truth = camera(1.5, 1.0);
        let pitched = Pose::from_parts(truth.translation, truth.rotation * pitch);
        let mut s = BaselineSession::new(
            &scene,
            &table,
            Baseline::Simp,
            BaselineParams::default(),
            &config(),
            &start(pitched),
        )
        .unwrap();
        let level = |p: &Pose| {
            // Camera y (down in the image) is world -z: no roll, no pitch.
            let down = p.rotation * Vector3::y();
            (down + Vector3::z()).norm()
        };
        for p in s.particles() {
            assert!(level(&p.pose) < 1e-9, "{:?}", p.pose);
            assert!((p.pose.translation.z - 0.75).abs() < 1e-9);
        }
        let r = s
            .step(&pitched, 0.0, &frame(0, 3), Some(&vec![2.0; 64 * 48]))
            .unwrap();
        let x = r.pose.translation.x;
        assert!((1.95..2.55).contains(&x), "estimate x {x:.3}");
        assert!(level(&r.pose) < 1e-9 && (r.pose.translation.z - 0.75).abs() < 1e-9);
        assert_eq!((r.frame, s.frames()), (1, 1));

        // A 2-d frame: rejected, nothing stepped.
        let before: Vec<Pose> = s.particles().iter().map(|p| p.pose).collect();
        // The odometry pitched 20 degrees now, and 0.5 m forward: held
        // level, its motion is 0.5 m along x.
        let forward = Pose::from_parts(
            Translation3::new(2.0, 1.0, 0.75),
            truth.rotation * pitch * pitch,
        );
        let e = s
            .step(&forward, 0.1, &frame(0, 2), Some(&vec![1.5; 64 * 48]))
            .unwrap_err();
        assert!(matches!(e, SessionError::BadFrame(_)), "{e}");
        // An odometry jump: rejected too.
        let far = Pose::from_parts(Translation3::new(5000.0, 1.0, 0.75), truth.rotation * pitch);
        let e = s
            .step(&far, 0.1, &frame(0, 3), Some(&vec![1.5; 64 * 48]))
            .unwrap_err();
        assert!(matches!(e, SessionError::OdometryJump(_)), "{e}");
        assert_eq!(s.frames(), 1);
        let after: Vec<Pose> = s.particles().iter().map(|p| p.pose).collect();
        assert_eq!(before, after);

        // 0.5 m forward, the wall 1.5 m ahead: x 2.5 to 3.0.
        let r = s
            .step(&forward, 0.1, &frame(0, 3), Some(&vec![1.5; 64 * 48]))
            .unwrap();
        let x = r.pose.translation.x;
        assert!((2.4..3.1).contains(&x), "estimate x {x:.3}");
        assert!(level(&r.pose) < 1e-9);
        assert_eq!((r.frame, s.frames()), (2, 2));
    }

    /// What a baseline cannot start from, or label with, is refused by
    /// the method's name.
    #[test]
    fn a_baseline_session_refuses_by_name() {
        let (scene, table) = plan_scene();
        let new = |b: Baseline, t: &EmbeddingTable, st: &Start| {
            BaselineSession::new(&scene, t, b, BaselineParams::default(), &config(), st)
                .err()
                .unwrap()
                .to_string()
        };
        let e = new(Baseline::Sedar, &table, &Start::Global);
        assert!(e.starts_with("SeDAR* starts from a pose"), "{e}");
        // Restarted: from a pose only, levelled, as many particles as at
        // the start; a global restart leaves the session as it was.
        let mut s = BaselineSession::new(
            &scene,
            &table,
            Baseline::Sedar,
            BaselineParams::default(),
            &config(),
            &start(camera(1.5, 1.0)),
        )
        .unwrap();
        let before: Vec<Pose> = s.particles().iter().map(|p| p.pose).collect();
        let e = s.reinitialize(&Start::Global).unwrap_err().to_string();
        assert!(e.starts_with("SeDAR* starts from a pose"), "{e}");
        let after: Vec<Pose> = s.particles().iter().map(|p| p.pose).collect();
        assert_eq!(before, after);
        let pitch = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.2);
        let target = camera(3.0, 2.5);
        let pitched = Pose::from_parts(target.translation, target.rotation * pitch);
        s.reinitialize(&Start::Pose {
            pose: pitched,
            sigma_m: 0.0,
            sigma_rad: 0.0,
        })
        .unwrap();
        assert_eq!(s.particles().len(), 256);
        for p in s.particles() {
            let d = (p.pose.translation.vector - target.translation.vector).norm();
            let r = p.pose.rotation.angle_to(&target.rotation);
            assert!(d < 1e-9 && r < 1e-9, "{:?}", p.pose);
        }
        let two = EmbeddingTable::new(
            vec![0, 1],
            vec!["a".into(), "b".into()],
            2,
            vec![1.0, 0.0, 0.0, 1.0],
        )
        .unwrap();
        let e = new(Baseline::Simp, &two, &start(camera(1.5, 1.0)));
        assert!(
            e.contains("2-d class embeddings, the floor plan's features are 3-d: SIMP* labels"),
            "{e}"
        );
        // A class table without classes: the table's fault (the server
        // answers FAILED_PRECONDITION for it), not the filter's.
        let refused = |b: Baseline, t: &EmbeddingTable, params: BaselineParams| {
            BaselineSession::new(&scene, t, b, params, &config(), &start(camera(1.5, 1.0)))
                .err()
                .unwrap()
        };
        let empty = EmbeddingTable::new(vec![], vec![], 3, vec![]).unwrap();
        let e = refused(Baseline::Sedar, &empty, BaselineParams::default());
        assert!(matches!(e, SessionError::ClassTable(_)), "{e:?}");
        assert!(e.to_string().contains("has no classes"), "{e}");
        // A distance cap that is no distance: the start's parameters'
        // fault, named as such.
        let nan = BaselineParams {
            max_distance: f64::NAN,
            ..BaselineParams::default()
        };
        let e = refused(Baseline::Simp, &table, nan);
        assert!(matches!(e, SessionError::Init(_)), "{e:?}");
        assert!(e.to_string().contains("baseline max distance"), "{e}");
    }
}
