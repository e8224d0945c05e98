//! Table I on synthetic sequences: OMCL on a floor plan (2-D block) and
//! the full 6-DoF pose in the 3-D map (3-D block), each on one tuning-range
//! sequence with an accuracy bound.

use omcl::experiment::features::builtin_table;
use omcl::experiment::mapping::BenchMap;
use omcl::experiment::table1_6dof::{SixDofMotion, sixdof_sequence, track_6dof};
use omcl::experiment::table1_floorplan::{TwoDParams, plan_scene, track_2d, track_baseline};
use omcl::experiment::variant::TABLE1_VARIANTS;
use omcl::experiment::{MapParams, MapSource, SimSequence};
use omcl::map::FloorPlanParams;
use omcl::mcl::FilterConfig;
use omcl::mcl::baselines::Baseline;

const BOUND_2D: f64 = 0.12;
const BOUND_6DOF: f64 = 0.2;
const BOUND_HEIGHT: f64 = 0.2;
use omcl::sim::features::Preset;
use std::sync::Arc;

use nalgebra::{UnitQuaternion, Vector3};
use omcl::geometry::Pose;
use omcl::session::{Session, SessionConfig, SessionError, SharedMap, Start};

/// OMCL_GT on the floor plan of sequence 1 (tuning range), 60 frames,
/// 512 particles, the block's filter: the horizontal APE stays within
/// 0.12 m (0.076 m since pixels are stratified over the plan's own rows
/// and the estimate's radius is 0.5 m, 0.091 since columns end below the
/// ceiling and the exponent is 240, 2026-11-27, 0.100 before; the README
/// has the ten held-out sequences, 1024 particles), and the baselines run
/// to the end of the same
/// sequence on the same plan.
#[test]
fn two_d_omcl_tracks_on_the_floor_plan() {
    let table = builtin_table().unwrap();
    let seq = SimSequence::generate(1, 60, &table).unwrap();
    let map = gt_map(&seq);
    let two_d = TwoDParams::default();
    let plan = plan_scene(&map, &FloorPlanParams::default(), &seq.table, &two_d).unwrap();
    // The plan is a one-layer map of the 3-D map's columns.
    assert!(plan.map.cells().iter().all(|c| c[2] == 0));
    assert!(plan.plan.len() > 1000 && plan.plan.len() < map.map.len());
    // OMCL's 2-D map adds each column's own floor (layer 1) and ceiling
    // (layer 2) under and over the plan, free columns included.
    let own = |z| {
        plan.sighted_map
            .cells()
            .iter()
            .filter(|c| c[2] == z)
            .count()
    };
    assert!(
        own(1) > plan.plan.len() && own(2) > 1000,
        "{} {}",
        own(1),
        own(2)
    );
    // And each occupied column's own base (layer 5) and top (layer 6):
    // the walls have both, free columns neither.
    assert!(
        own(5) > plan.plan.len() / 4 && own(6) > plan.plan.len() / 4,
        "{} {} of {}",
        own(5),
        own(6),
        plan.plan.len()
    );
    assert!(own(5) <= plan.plan.len() && own(6) <= plan.plan.len());
    // Pixels are stratified over the plan's own rows and the floor and
    // ceiling words (the last two rows), not over the rows the sighted
    // map derives (some own floors, ceilings, bases and tops have rows of
    // their own).
    let rows = plan.sighted_map.db().len();
    let own_rows = plan.plan.db().len();
    assert_eq!(plan.strata.len(), rows);
    assert!(rows > own_rows + 2, "{rows} rows, {own_rows} the plan's");
    for (r, &marked) in plan.strata.iter().enumerate() {
        assert_eq!(marked, r < own_rows || r >= rows - 2, "row {r}");
    }
    // A negative or non-finite weight of the words, or a height of the
    // bases and tops that is not positive, not finite or so tall that
    // the base and top meet, is refused by name.
    for (w, h) in [
        (-1.0, 0.1),
        (f32::INFINITY, 0.1),
        (0.5, 0.0),
        (0.5, f32::NAN),
        // Taller than half the window: the base and top would meet.
        (0.5, 1e30),
        (0.5, 2.0),
    ] {
        let bad = TwoDParams {
            surfaces: Some(w),
            skirt: Some(h),
            ..two_d
        };
        let e = plan_scene(&map, &FloorPlanParams::default(), &seq.table, &bad)
            .err()
            .expect("refused");
        let name = if w == 0.5 {
            "two_d.skirt"
        } else {
            "two_d.surfaces"
        };
        assert!(e.to_string().contains(name), "{e}");
    }
    // The block's filter (8192 pixels, exponent 240).
    let filter = FilterConfig {
        seed: 1,
        ..FilterConfig::floor_plan()
    };
    let (r, _) = track_2d(&seq, &plan, Preset::Gt, filter, 512, &TwoDParams::default()).unwrap();
    assert_eq!(r.errors_m.len(), 60);
    eprintln!("2-D OMCL_GT RMSE {:.3} m", r.stats.rmse);
    assert!(r.stats.rmse < BOUND_2D, "2-D RMSE {:.3} m", r.stats.rmse);
    // Frames of another feature dimension than the plan's: a named error.
    let caster: std::sync::Arc<dyn omcl::raycast::RayCaster> = plan.caster.clone();
    let mut f = omcl::mcl::Filter::new(
        &plan.map,
        caster,
        seq.intrinsics,
        filter,
        vec![omcl::mcl::Particle::new(seq.poses()[0], 1.0)],
    )
    .unwrap();
    let (w, h) = (seq.intrinsics.width, seq.intrinsics.height);
    let wrong = omcl::mcl::DenseFeatures {
        width: w,
        height: h,
        dim: 3,
        data: vec![1.0; (w * h * 3) as usize],
    };
    let e = f
        .step(&omcl::geometry::Pose::identity(), &wrong)
        .unwrap_err();
    assert!(
        matches!(
            e,
            omcl::mcl::MclError::DimMismatch { expected, got: 3 } if expected == plan.plan.db().dim()
        ),
        "{e}"
    );
    for b in [Baseline::Sedar, Baseline::Simp] {
        let r =
            track_baseline(&seq, &plan, b, &Default::default(), Preset::Gt, filter, 256).unwrap();
        assert_eq!(r.errors_m.len(), 60);
        assert!(r.errors_m.iter().all(|e| e.is_finite()));
        eprintln!("{} RMSE {:.3} m", b.name(), r.stats.rmse);
    }

    // A session on the plan (`SharedMap::floor_plan`, what `omcl localize
    // --floorplan` runs) holds the camera level: a start pose pitched 10
    // degrees and odometry that climbs, pitches and rolls leave every
    // particle level at the start's height (global and prompt starts:
    // `two_d_starts_globally_and_from_words_over_the_3d_floor`).
    let scene = plan_scene(&map, &FloorPlanParams::default(), &seq.table, &two_d).unwrap();
    let shared = Arc::new(SharedMap::floor_plan("plan", scene));
    let config = SessionConfig {
        intrinsics: seq.intrinsics,
        particles: 64,
        filter,
        floor: Default::default(),
        floor_feature: None,
        ground: false,
    };
    let turn = |pitch: f64, roll: f64| {
        UnitQuaternion::from_euler_angles(pitch.to_radians(), 0.0, 0.0)
            * UnitQuaternion::from_euler_angles(0.0, 0.0, roll.to_radians())
    };
    let p0 = seq.poses()[0];
    let z0 = p0.translation.vector.z;
    let start = Start::Pose {
        pose: Pose::from_parts(p0.translation, p0.rotation * turn(10.0, 0.0)),
        sigma_m: 0.1,
        sigma_rad: 0.1,
    };
    let mut session = Session::new(shared, config, &start).unwrap();
    let all_level = |s: &Session| {
        s.particles().iter().all(|p| {
            let y = p.pose.rotation * Vector3::y();
            (y.z + 1.0).abs() < 1e-9 && (p.pose.translation.vector.z - z0).abs() < 1e-9
        })
    };
    assert!(all_level(&session));
    let dim = plan.plan.db().dim();
    let (w, h) = (seq.intrinsics.width, seq.intrinsics.height);
    let frame = omcl::mcl::DenseFeatures {
        width: w,
        height: h,
        dim,
        data: (0..(w * h) as usize * dim)
            .map(|i| ((i % 7) as f32 - 3.0) / 3.0)
            .collect(),
    };
    for k in 1..4 {
        let k = k as f64;
        let mut odom = Pose::from_parts(p0.translation, p0.rotation * turn(4.0 * k, 3.0 * k));
        odom.translation.vector += Vector3::new(0.1 * k, 0.0, 0.05 * k);
        session.step(&odom, k, &frame).unwrap();
        assert!(all_level(&session), "step {k}");
    }
}

/// OMCL_GT with the 6-DoF filter ([`FilterConfig::six_dof`]: full motion
/// noise, two layers of progressive correction, 4096 pixels, exponent 240)
/// on sequence 1 with height, pitch and roll changes and 6-DoF odometry
/// noise: the 3-D APE stays within 0.2 m (0.131 m on 2026-11-26, 0.146 m
/// with the block's filter before; one layer: 0.306 m), the estimated height follows the true one, and the same
/// run without the second layer (the plain filter, each frame weighed
/// once) is farther off: the six-dimensional cloud is too sparse for the
/// sharpened likelihood without it.
#[test]
fn six_dof_omcl_tracks_height_and_pitch_changes() {
    let table = builtin_table().unwrap();
    let seq = sixdof_sequence(1, 60, &table, &SixDofMotion::default()).unwrap();
    let map = gt_map(&seq);
    // 512 particles x 4096 rays (the block's own default is 1024 x 4096):
    // half the casts, and a cloud sparse enough that the second layer's
    // part shows.
    let filter = FilterConfig {
        seed: 1,
        ..FilterConfig::six_dof()
    };
    let r = track_6dof(&seq, &map, &TABLE1_VARIANTS[0], filter, 512).unwrap();
    let plain = FilterConfig {
        anneal: None,
        ..filter
    };
    let p = track_6dof(&seq, &map, &TABLE1_VARIANTS[0], plain, 512).unwrap();
    eprintln!(
        "6-DoF OMCL_GT RMSE {:.3} m with two layers, {:.3} m with one",
        r.stats.rmse, p.stats.rmse
    );
    assert!(
        r.stats.rmse < BOUND_6DOF,
        "6-DoF RMSE {:.3} m",
        r.stats.rmse
    );
    assert!(
        r.stats.rmse < p.stats.rmse,
        "two layers {:.3} m, one {:.3} m",
        r.stats.rmse,
        p.stats.rmse
    );
    let dz: f64 = r
        .estimates
        .iter()
        .zip(seq.poses())
        .map(|(e, t)| (e.translation.z - t.translation.z).abs())
        .sum::<f64>()
        / 60.0;
    assert!(dz < BOUND_HEIGHT, "mean height error {dz:.3} m");
}

/// Global and prompt starts on a floor plan (since 2026-12-01): without
/// the 3-D map the plan was projected from they are refused by name; with
/// it ([`SharedMap::with_floor_map`]) they place level cameras over its
/// floor voxels, as in 3-D (a prompt's on the floor voxels the 3-D prompt
/// matching keeps), each at 1.5 m over its voxel's top, and a 2-D run
/// from either start localizes (tuning sequence 0, 40 frames, the 2-D
/// block's filter with 512 particles: measured on 2026-12-01, within 0.2
/// m at step 4 from the global start and at step 5 from the prompt
/// "stove, picture, plant, counter", at most 0.26 m over the last ten
/// frames; bounds 15 steps and 0.3 m; the held-out Table V on the floor
/// plan is in the README).
#[test]
fn two_d_starts_globally_and_from_words_over_the_3d_floor() {
    use omcl::experiment::run::{RunSpec, Start as RunStart, run_on};
    use omcl::mcl::init::{floor_voxels, prompt_floor_voxels};
    use std::collections::HashSet;
    let table = builtin_table().unwrap();
    let seq = SimSequence::generate(0, 40, &table).unwrap();
    let map = gt_map(&seq);
    let two_d = TwoDParams::default();
    let scene = || plan_scene(&map, &FloorPlanParams::default(), &seq.table, &two_d).unwrap();
    let floor = seq.table.text_feature("floor").unwrap().to_vec();
    let config = config_global(&seq, &floor);
    let bare = Arc::new(SharedMap::floor_plan("plan", scene()));
    let e = Session::new(bare, config.clone(), &Start::Global)
        .err()
        .expect("refused");
    assert!(matches!(e, SessionError::PoseStartOnly(_)), "{e}");
    assert!(e.to_string().contains("without the 3-D map"), "{e}");

    let shared =
        Arc::new(SharedMap::floor_plan("plan", scene()).with_floor_map(Arc::new(map.map.clone())));
    // The 3-D map's floor voxels, by horizontal cell, with their tops.
    let res = map.map.grid().resolution;
    let cells_of = |leaves: &[usize]| -> HashSet<(i32, i32, i64)> {
        leaves
            .iter()
            .map(|&l| {
                let c = omcl::map::key::decode(map.map.codes()[l]);
                let top = map.map.grid().center(c).z + 0.5 * res;
                (c[0], c[1], (top * 1e6).round() as i64)
            })
            .collect()
    };
    let on = |p: &omcl::mcl::Particle, cells: &HashSet<(i32, i32, i64)>| {
        let t = p.pose.translation.vector;
        let c = map.map.grid().cell_of(&t).unwrap();
        let y = p.pose.rotation * Vector3::y();
        (y.z + 1.0).abs() < 1e-9
            && cells.contains(&(c[0], c[1], ((t.z - 1.5) * 1e6).round() as i64))
    };
    let all_floor = cells_of(&floor_voxels(&map.map, &floor, 0.9).unwrap());
    let s = Session::new(shared.clone(), config.clone(), &Start::Global).unwrap();
    assert_eq!(s.particles().len(), 256);
    assert!(s.particles().iter().all(|p| on(p, &all_floor)));

    // A prompt drawn as Table V draws them (3 to 5 object classes the
    // ground truth has within 2 m of the start): the first of the bench's
    // draws whose words the 3-D prompt matching finds together.
    let params = omcl::mcl::PromptParams::default();
    let feature = |w: &String| seq.table.text_feature(w).unwrap().to_vec();
    let (words, near) = (0..20u64)
        .find_map(|k| {
            let words = omcl::experiment::table5::prompt_words(&seq, 0, 0x5eed ^ k);
            let f: Vec<Vec<f32>> = words.iter().map(feature).collect();
            let near = prompt_floor_voxels(&map.map, &floor, &f, 0.9, &params).ok()?;
            Some((words, near))
        })
        .expect("a prompt that places particles");
    let near = cells_of(&near);
    assert!(
        near.len() * 2 < all_floor.len(),
        "{words:?}: {} of {}",
        near.len(),
        all_floor.len()
    );
    let prompt = Start::Prompt {
        words: words.iter().map(feature).collect(),
        params,
    };
    let s = Session::new(shared.clone(), config.clone(), &prompt).unwrap();
    assert!(s.particles().iter().all(|p| on(p, &near)), "{words:?}");

    // Recovery from a pose start held 0.2 m under the truth: frames seen
    // from elsewhere (the sequence's frame 30 at the pose of frame k) make
    // the filter inject, and every injected camera stands at the start's
    // height, as the tracked ones are held (recovery's own draw puts them
    // 1.5 m over their voxel's top).
    let p0 = seq.poses()[0];
    let z0 = p0.translation.vector.z - 0.2;
    let mut start_pose = p0;
    start_pose.translation.vector.z = z0;
    let with_recovery = SessionConfig {
        filter: FilterConfig {
            recovery: Some(omcl::mcl::recovery::RecoveryParams::default()),
            ..FilterConfig::floor_plan()
        },
        ..config_global(&seq, &floor)
    };
    let mut s = Session::new(
        shared.clone(),
        with_recovery,
        &Start::Pose {
            pose: start_pose,
            sigma_m: 0.1,
            sigma_rad: 0.1,
        },
    )
    .unwrap();
    let model = omcl::experiment::features::feature_model(&seq, Preset::Gt, 0x10c);
    let rows = omcl::experiment::class_rows(&seq, shared.map());
    let mut injected = 0;
    for k in 0..12 {
        let shown = if k < 4 { k } else { 30 };
        let frame = seq.render(shown);
        let f = omcl::experiment::GridFeatures::new(
            omcl::experiment::SimFrameFeatures::new(
                &model,
                Preset::Gt,
                &frame,
                shown as u64,
                &rows,
            ),
            4,
        );
        let r = s.step_by(&seq.increment(k), k as f64, &f).unwrap();
        injected += r.step.injected;
        assert!(
            s.particles()
                .iter()
                .all(|p| (p.pose.translation.vector.z - z0).abs() < 1e-9),
            "frame {k}: a particle off the start's height"
        );
    }
    assert!(injected > 0, "no injection to check");

    // 2-D runs from both starts, horizontal errors.
    let model = omcl::experiment::features::feature_model(&seq, Preset::Gt, 0x10c);
    for (start, bound) in [
        (RunStart::Global, 15),
        (RunStart::Prompt(words.clone()), 15),
    ] {
        let spec = RunSpec {
            filter: FilterConfig {
                seed: 3,
                ..FilterConfig::floor_plan()
            },
            particles: 512,
            start: start.clone(),
            first: 0,
            frames: 40,
            preset: Preset::Gt,
            encoder_stride: 1,
        };
        let r = run_on(&seq, shared.clone(), &model, &spec).unwrap();
        let reached = r.errors_m.iter().position(|&e| e <= 0.2).map(|k| k + 1);
        eprintln!(
            "{start:?}: within 0.2 m at step {reached:?}; errors {:.2?}",
            r.errors_m
        );
        assert!(
            reached.is_some_and(|k| k <= bound),
            "{start:?}: {reached:?}"
        );
        let last = &r.errors_m[30..];
        assert!(last.iter().all(|&e| e <= 0.3), "{start:?}: {last:.3?}");
    }
}

/// 256 particles, the 2-D block's filter, the word "floor" given.
fn config_global(seq: &SimSequence, floor: &[f32]) -> SessionConfig {
    SessionConfig {
        intrinsics: seq.intrinsics,
        particles: 256,
        filter: FilterConfig::floor_plan(),
        floor: Default::default(),
        floor_feature: Some(floor.to_vec()),
        ground: false,
    }
}

/// The map of `seq` from its ground-truth features, the bench's defaults.
fn gt_map(seq: &SimSequence) -> BenchMap {
    BenchMap::build(
        seq,
        MapSource::Features(Preset::Gt),
        &MapParams::default(),
        &|_| {},
    )
    .unwrap()
}

/// Table V on the floor plan projects each map with its settings
/// (`omcl bench table5-floorplan --set plan.* two_d.*`): the defaults
/// run; a band above everything the map holds is refused by the plan's
/// projection, naming the band, so the settings reach it.
#[test]
fn table5_on_the_plan_projects_with_its_settings() {
    use omcl::experiment::plan_settings::PlanSettings;
    use omcl::experiment::run::GlobalSpec;
    use omcl::experiment::table5::global_runs;
    let table = builtin_table().unwrap();
    let seq = SimSequence::generate(0, 20, &table).unwrap();
    let map = gt_map(&seq);
    let spec = |plan: FloorPlanParams| GlobalSpec {
        preset: Preset::Gt,
        filter: FilterConfig::floor_plan(),
        particles: 64,
        starts: 1,
        max_steps: 2,
        prompt: false,
        floor_plan: Some(PlanSettings {
            plan,
            two_d: TwoDParams::default(),
        }),
    };
    let runs = global_runs(&seq, &map, &spec(FloorPlanParams::default())).unwrap();
    assert_eq!(runs.len(), 1);
    assert_eq!(runs[0].error, None);
    let high = FloorPlanParams {
        band_min: 50.0,
        band_max: 60.0,
    };
    let e = global_runs(&seq, &map, &spec(high)).expect_err("refused");
    assert!(e.to_string().contains("height band [50, 60]"), "{e}");
}
