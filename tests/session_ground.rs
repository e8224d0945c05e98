//! A session on a 3-D map that holds the camera to the ground
//! (`SessionConfig::ground`, `omcl localize --ground`): a tilted start keeps
//! its height and tilt through odometry that climbs, pitches and rolls; a
//! new start brings its own; what it cannot do is refused by name.

use std::sync::Arc;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use omcl::experiment::features::builtin_table;
use omcl::experiment::mapping::BenchMap;
use omcl::experiment::{MapParams, MapSource, SimSequence};
use omcl::geometry::Pose;
use omcl::mcl::{DenseFeatures, FilterConfig, MotionMode, Particle};
use omcl::session::{Session, SessionConfig, SessionError, SharedMap, Start};
use omcl::sim::features::Preset;

/// Pitch and roll (degrees, about the camera's x and z axes).
fn turn(pitch: f64, roll: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_euler_angles(pitch.to_radians(), 0.0, 0.0)
        * UnitQuaternion::from_euler_angles(0.0, 0.0, roll.to_radians())
}

/// The world z of the camera's forward and image-y axes (its tilt against
/// gravity, whatever its heading) and its height.
fn hold_of(p: &Pose) -> [f64; 3] {
    [
        (p.rotation * Vector3::z()).z,
        (p.rotation * Vector3::y()).z,
        p.translation.vector.z,
    ]
}

fn all_held(ps: &[Particle], want: [f64; 3]) -> bool {
    ps.iter().all(|p| {
        let h = hold_of(&p.pose);
        (0..3).all(|k| (h[k] - want[k]).abs() < 1e-9)
    })
}

#[test]
fn a_ground_session_keeps_the_start_height_and_tilt() {
    let table = builtin_table().unwrap();
    let seq = SimSequence::generate(1, 20, &table).unwrap();
    let map = BenchMap::build(
        &seq,
        MapSource::Features(Preset::Gt),
        &MapParams::default(),
        &|_| {},
    )
    .unwrap();
    let shared = Arc::new(SharedMap::from_parts(
        "room",
        map.map.clone(),
        map.caster.clone(),
    ));
    let config = SessionConfig {
        intrinsics: seq.intrinsics,
        particles: 64,
        filter: FilterConfig {
            seed: 2,
            ..FilterConfig::default()
        },
        floor: Default::default(),
        floor_feature: None,
        ground: true,
    };
    let p0 = seq.poses()[0];
    let tilted = Pose::from_parts(p0.translation, p0.rotation * turn(-10.0, 3.0));
    let start = Start::Pose {
        pose: tilted,
        sigma_m: 0.1,
        sigma_rad: 0.1,
    };
    let want = hold_of(&tilted);
    assert!(want[0] < -0.15, "pitched down: {want:?}");

    // What it cannot do: motion noise off the plane, and recovery (which
    // injects level cameras) from a tilted start.
    for (filter, what) in [
        (
            FilterConfig {
                motion: omcl::mcl::MotionModel {
                    mode: MotionMode::Full,
                    ..Default::default()
                },
                ..config.filter
            },
            "motion",
        ),
        (
            FilterConfig {
                recovery: Some(Default::default()),
                ..config.filter
            },
            "recovery",
        ),
    ] {
        let c = SessionConfig {
            filter,
            floor_feature: Some(vec![0.0; map.map.db().dim()]),
            ..config.clone()
        };
        let e = Session::new(shared.clone(), c, &start)
            .err()
            .expect("refused");
        match what {
            "motion" => assert!(
                matches!(e, SessionError::GroundMotion(MotionMode::Full)),
                "{e}"
            ),
            _ => {
                assert!(
                    matches!(e, SessionError::TiltedRecovery(t) if (t - 10.4).abs() < 0.1),
                    "{e}"
                );
                assert!(e.to_string().contains("10.4 degrees from level"), "{e}");
            }
        }
    }

    let mut session = Session::new(shared, config, &start).unwrap();
    assert!(all_held(session.particles(), want));
    let dim = map.map.db().dim();
    let (w, h) = (seq.intrinsics.width, seq.intrinsics.height);
    let frame = DenseFeatures {
        width: w,
        height: h,
        dim,
        data: (0..(w * h) as usize * dim)
            .map(|i| ((i % 7) as f32 - 3.0) / 3.0)
            .collect(),
    };
    // Odometry poses that drive forward, turn, climb, pitch and roll.
    let odom = |k: f64| {
        let mut o = Pose::from_parts(
            p0.translation,
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.1 * k)
                * p0.rotation
                * turn(-10.0 + 4.0 * k, 3.0 - 3.0 * k),
        );
        o.translation.vector += Vector3::new(0.1 * k, 0.05 * k, 0.05 * k);
        o
    };
    for k in 0..4 {
        let r = session.step(&odom(k as f64), k as f64, &frame).unwrap();
        assert!(all_held(session.particles(), want), "step {k}");
        let e = hold_of(&r.pose);
        assert!((e[2] - want[2]).abs() < 1e-9, "step {k}: estimate {e:?}");
    }
    // Increments: the same.
    let inc = Pose::from_parts(Translation3::new(0.05, 0.02, 0.1), turn(5.0, -2.0));
    session.step_by(&inc, 5.0, &frame).unwrap();
    assert!(all_held(session.particles(), want));

    // A new level start: the session holds the camera level from then on.
    session
        .reinitialize(&Start::Pose {
            pose: p0,
            sigma_m: 0.1,
            sigma_rad: 0.1,
        })
        .unwrap();
    let level = hold_of(&p0);
    assert!(
        level[0].abs() < 1e-9 && (level[1] + 1.0).abs() < 1e-9,
        "{level:?}"
    );
    for k in 6..8 {
        session.step(&odom(k as f64), k as f64, &frame).unwrap();
        assert!(all_held(session.particles(), level), "step {k}");
    }
}
