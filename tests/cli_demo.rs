//! `omcl demo` runs the whole pipeline on the built-in world and leaves its
//! outputs behind (a short sequence, to keep the test quick).

use std::process::Command;

#[test]
fn demo_runs_end_to_end() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo");
    let o = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args([
            "demo",
            "--out",
            out.to_str().unwrap(),
            "--frames",
            "12",
            // The closing `omcl bench` step is tested in cli_bench.rs.
            "--bench-sequences",
            "0",
            // A short street: the KITTI-layout run is tested at length in
            // cli_localize_kitti.rs.
            "--street-frames",
            "15",
        ])
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{text}");
    for f in [
        "apartment.omcl",
        "estimate.txt",
        "diagnostics.csv",
        "toilet_heat.ply",
        "trajectory.png",
        "apartment/poses.txt",
        "street.omcl",
        "street_estimate.txt",
        "street_metrics.json",
        "street_trajectory.png",
        "street/sequences/00/labels_2/000014.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing\n{text}");
    }
    let est = std::fs::read_to_string(out.join("estimate.txt")).unwrap();
    assert_eq!(est.lines().filter(|l| !l.starts_with('#')).count(), 12);
    // The APE statistics are printed and finite.
    let rmse: f64 = text
        .lines()
        .find_map(|l| l.trim().strip_prefix("rmse"))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no rmse line\n{text}"));
    assert!(rmse.is_finite() && rmse < 1.0, "rmse {rmse}\n{text}");
    let map = omcl::map::load(&out.join("apartment.omcl")).unwrap();
    assert!(map.len() > 10_000);
}
