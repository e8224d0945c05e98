//! Properties the trajectory metrics must have whatever the input.

use nalgebra::{Rotation3, Translation3, UnitQuaternion, Vector3};
use omcl::eval::align::{Alignment, align_trajectory, umeyama};
use omcl::eval::ape::{PoseRelation, ape};
use omcl::eval::rpe::{Delta, RpeOptions, rpe};
use omcl::geometry::Pose;
use omcl::trajectory::Trajectory;
use proptest::prelude::*;

fn pose(t: [f64; 3], r: [f64; 3]) -> Pose {
    Pose::from_parts(
        Translation3::new(t[0], t[1], t[2]),
        UnitQuaternion::from_euler_angles(r[0], r[1], r[2]),
    )
}

fn trajectory() -> impl Strategy<Value = Trajectory> {
    prop::collection::vec(
        (
            prop::array::uniform3(-50.0f64..50.0),
            prop::array::uniform3(-3.1f64..3.1),
        ),
        4..40,
    )
    .prop_map(|v| Trajectory::from_poses(v.into_iter().map(|(t, r)| pose(t, r)).collect()).unwrap())
}

/// A reference and an estimate: the reference moved by a similarity, plus
/// per-pose noise.
fn pair() -> impl Strategy<Value = (Trajectory, Trajectory, f64)> {
    (
        trajectory(),
        prop::array::uniform3(-100.0f64..100.0),
        prop::array::uniform3(-3.1f64..3.1),
        0.2f64..5.0,
        prop::collection::vec(prop::array::uniform3(-0.5f64..0.5), 40),
    )
        .prop_map(|(reference, t, r, s, noise)| {
            let frame = pose(t, r);
            let poses = reference
                .poses()
                .iter()
                .zip(&noise)
                .map(|(p, n)| {
                    let mut q = frame * p;
                    q.translation.vector = frame.rotation * (s * p.translation.vector)
                        + frame.translation.vector
                        + Vector3::from(*n);
                    q
                })
                .collect();
            let estimate = Trajectory::from_poses(poses).unwrap();
            (reference, estimate, s)
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Umeyama minimizes the squared error: Sim(3) <= SE(3) <= no alignment
    /// (the estimate is compared to the reference, so the fit is the other
    /// way round from the construction above).
    #[test]
    fn alignment_never_increases_rmse((reference, estimate, _) in pair()) {
        let rmse = |a| {
            let (aligned, _) = align_trajectory(&estimate, &reference, a, None).unwrap();
            ape(&reference, &aligned, PoseRelation::Translation).unwrap().stats.rmse
        };
        let (none, se3, sim3) = (rmse(Alignment::None), rmse(Alignment::Se3), rmse(Alignment::Sim3));
        prop_assert!(se3 <= none * (1.0 + 1e-9) + 1e-9, "se3 {se3} > none {none}");
        prop_assert!(sim3 <= se3 * (1.0 + 1e-9) + 1e-9, "sim3 {sim3} > se3 {se3}");
        // Origin alignment puts the first estimated pose on the reference's.
        let (aligned, _) = align_trajectory(&estimate, &reference, Alignment::Origin, None).unwrap();
        let first = ape(&reference, &aligned, PoseRelation::Translation).unwrap().errors[0];
        prop_assert!(first < 1e-9);
    }

    /// Without noise the similarity is recovered exactly.
    #[test]
    fn umeyama_recovers_a_similarity(
        x in prop::collection::vec(prop::array::uniform3(-20.0f64..20.0), 4..30),
        r in prop::array::uniform3(-3.1f64..3.1),
        t in prop::array::uniform3(-100.0f64..100.0),
        s in 0.1f64..10.0,
    ) {
        let x: Vec<Vector3<f64>> = x.into_iter().map(Vector3::from).collect();
        let rot = Rotation3::from_euler_angles(r[0], r[1], r[2]);
        let y: Vec<_> = x.iter().map(|p| s * (rot * p) + Vector3::from(t)).collect();
        // Random points in a 40 m cube are never collinear in practice.
        let sim = umeyama(&x, &y, true);
        prop_assert!(sim.is_ok(), "{sim:?}");
        let sim = sim.unwrap();
        prop_assert!((sim.scale - s).abs() < 1e-9 * s);
        for (p, q) in x.iter().zip(&y) {
            let mapped = sim.scale * (sim.rotation * p) + sim.translation;
            prop_assert!((mapped - q).norm() < 1e-6 * (1.0 + q.norm()));
        }
    }

    /// RPE compares relative motions, so a rigid change of the estimate's
    /// world frame leaves it unchanged.
    #[test]
    fn rpe_ignores_the_estimate_frame(
        (reference, estimate, _) in pair(),
        t in prop::array::uniform3(-100.0f64..100.0),
        r in prop::array::uniform3(-3.1f64..3.1),
        delta in 1usize..4,
    ) {
        let moved = estimate.transformed(&pose(t, r));
        for relation in [PoseRelation::Translation, PoseRelation::RotationAngleDeg] {
            let o = RpeOptions { relation, delta: Delta::Frames(delta), ..RpeOptions::default() };
            // 4 to 40 poses and a delta of 1 to 3 frames: both must succeed.
            let a = rpe(&reference, &estimate, &o).unwrap();
            let b = rpe(&reference, &moved, &o).unwrap();
            prop_assert!(!a.errors.is_empty());
            prop_assert_eq!(a.errors.len(), b.errors.len());
            for (x, y) in a.errors.iter().zip(&b.errors) {
                prop_assert!((x - y).abs() < 1e-6 * (1.0 + x.abs()));
            }
        }
    }
}
