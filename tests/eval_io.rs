//! Pose-file reading and writing on real files and generated ones.

mod common;

use common::shared;

use nalgebra::{Translation3, UnitQuaternion, Vector3};
use omcl::geometry::Pose;
use omcl::io::poses::{PoseFormat, PosesError, read_poses, read_times, write_poses};
use omcl::trajectory::Trajectory;
use proptest::prelude::*;

#[test]
fn reads_the_real_trajectories() {
    let dir = shared("trajectories");
    for (name, format, count) in [
        ("KITTI_00_gt.txt", PoseFormat::Kitti, 4541),
        ("KITTI_00_ORB.txt", PoseFormat::Kitti, 4541),
        ("freiburg1_xyz-groundtruth.txt", PoseFormat::Tum, 3000),
        ("freiburg1_xyz-rgbdslam.txt", PoseFormat::Tum, 788),
        ("fr2_desk_groundtruth.txt", PoseFormat::Tum, 20957),
        ("fr2_desk_ORB.txt", PoseFormat::Tum, 2893),
    ] {
        let f = read_poses(&dir.join(name)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((f.format, f.trajectory.len()), (format, count), "{name}");
    }
    // First data line of the fr1 ground truth, after three comment lines:
    // 1305031098.6659 1.3563 0.6305 1.6380 0.6132 0.5962 -0.3311 -0.3986
    let gt = read_poses(&dir.join("freiburg1_xyz-groundtruth.txt")).unwrap();
    assert_eq!(gt.trajectory.stamps()[0], 1305031098.6659);
    let p = gt.trajectory.poses()[0];
    assert_eq!(p.translation.vector, Vector3::new(1.3563, 0.6305, 1.6380));
    let q = p.rotation.quaternion();
    let n = (0.6132f64.powi(2) + 0.5962f64.powi(2) + 0.3311f64.powi(2) + 0.3986f64.powi(2)).sqrt();
    assert!((q.w - -0.3986 / n).abs() < 1e-12 && (q.i - 0.6132 / n).abs() < 1e-12);
    // KITTI 00 ground truth pose 1 translation column.
    let kitti = read_poses(&dir.join("KITTI_00_gt.txt")).unwrap();
    let t = kitti.trajectory.poses()[1].translation.vector;
    assert_eq!(t, Vector3::new(-4.690294e-02, -2.839928e-02, 8.586941e-01));
    let times = read_times(&dir.join("KITTI_00_gt_times.txt")).unwrap();
    assert_eq!(times.len(), 4541);
    let timed = kitti.trajectory.with_stamps(times).unwrap();
    assert_eq!(timed.stamps()[1], 1.037359e-01);
}

#[test]
fn kitti_round_trip_on_real_file_is_exact_after_projection() {
    let dir = shared("trajectories");
    let orig = read_poses(&dir.join("KITTI_00_ORB.txt"))
        .unwrap()
        .trajectory;
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("orb.txt");
    write_poses(&out, &orig, PoseFormat::Kitti).unwrap();
    let back = read_poses(&out).unwrap().trajectory;
    for (a, b) in orig.poses().iter().zip(back.poses()) {
        assert_eq!(a.translation, b.translation);
        assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
    }
}

#[test]
fn file_errors_name_the_file_and_line() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("bad.txt");
    std::fs::write(
        &p,
        "# t x y z qx qy qz qw\n0 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 inf\n",
    )
    .unwrap();
    let e = read_poses(&p).unwrap_err();
    assert!(matches!(e, PosesError::Parse { line: 3, .. }), "{e}");
    assert!(e.to_string().contains("bad.txt:3:"), "{e}");
    let missing = tmp.path().join("missing.txt");
    assert!(
        read_poses(&missing)
            .unwrap_err()
            .to_string()
            .contains("missing.txt")
    );
    // A write into a missing directory fails and creates nothing.
    let t = Trajectory::from_poses(vec![Pose::identity()]).unwrap();
    let nowhere = tmp.path().join("no/such/dir/out.txt");
    assert!(write_poses(&nowhere, &t, PoseFormat::Tum).is_err());
    // Overwriting keeps the file whole: the new content replaces the old.
    let out = tmp.path().join("out.txt");
    std::fs::write(&out, "old").unwrap();
    write_poses(&out, &t, PoseFormat::Tum).unwrap();
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "0 0 0 0 0 0 0 1\n");
}

fn pose_strategy() -> impl Strategy<Value = (f64, [f64; 3], [f64; 3])> {
    (
        0.0f64..1e9,
        prop::array::uniform3(-1e4f64..1e4),
        prop::array::uniform3(-3.2f64..3.2),
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn tum_round_trip_is_bit_exact(mut rows in prop::collection::vec(pose_strategy(), 1..20)) {
        rows.sort_by(|a, b| a.0.total_cmp(&b.0));
        let stamps = rows.iter().map(|r| r.0).collect();
        let poses = rows
            .iter()
            .map(|(_, t, r)| {
                Pose::from_parts(
                    Translation3::new(t[0], t[1], t[2]),
                    UnitQuaternion::from_euler_angles(r[0], r[1], r[2]),
                )
            })
            .collect();
        let traj = Trajectory::new(stamps, poses).unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let p = tmp.path().join("t.txt");
        write_poses(&p, &traj, PoseFormat::Tum).unwrap();
        let back = read_poses(&p).unwrap();
        prop_assert_eq!(back.format, PoseFormat::Tum);
        prop_assert_eq!(back.trajectory.stamps(), traj.stamps());
        for (a, b) in back.trajectory.poses().iter().zip(traj.poses()) {
            prop_assert_eq!(a.translation, b.translation);
            prop_assert!(a.rotation.angle_to(&b.rotation) < 1e-12);
        }
    }

    #[test]
    fn garbage_never_panics(text in "[0-9eE.,# \\-+a-z\\n]{0,200}") {
        let _ = omcl::io::poses::parse_poses(&text, std::path::Path::new("x"), None);
    }
}
