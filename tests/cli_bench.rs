//! `omcl bench` on a tiny benchmark: every experiment writes its Markdown
//! and JSON tables and its figures, with values in range.

mod common;

use std::process::Command;

fn bench(args: &[&str]) -> (std::process::Output, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .arg("bench")
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr);
    (o, text)
}

#[test]
fn table1_and_table2_write_tables_and_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let small = [&["--sequences", "1"][..], &common::TINY_RUN, &["-o", out]].concat();
    let (o, text) = bench(&[&["table1"], &small[..]].concat());
    assert!(o.status.success(), "{text}");
    for f in [
        "table1.md",
        "table1.json",
        "figure4_OMCL_GT.png",
        "figure4_OMCL_GT.svg",
        "figure4_OMCL_LSeg.png",
        "figure4_OMCL_GT_exact.png",
        "figure4_OMCL_auto_LSeg.png",
        "figure4_OMCL_Open_LSeg.png",
    ] {
        assert!(dir.path().join(f).exists(), "{f} missing\n{text}");
    }
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("table1.json")).unwrap())
            .unwrap();
    let rows = rows.as_array().unwrap();
    let names: Vec<&str> = rows
        .iter()
        .map(|r| r["variant"].as_str().unwrap())
        .collect();
    assert_eq!(
        names,
        [
            "OMCL_GT",
            "OMCL_LSeg",
            "OMCL_auto_LSeg",
            "OMCL_Open_LSeg",
            "OMCL_GT_exact"
        ]
    );
    let k: Vec<f64> = rows
        .iter()
        .map(|r| r["map_rows"].as_f64().unwrap())
        .collect();
    // Grounded maps hold at most the 29 class rows; the ungrounded "auto"
    // map keeps its blended voxel means as rows of their own.
    for (n, k) in names.iter().zip(&k) {
        assert!(
            *n == "OMCL_auto_LSeg" || (1.0..=29.0).contains(k),
            "{n}: K = {k}"
        );
    }
    assert!(k[2] > k[1], "auto K {} vs grounded {}", k[2], k[1]);
    for r in rows {
        // The encoder's work comes on top of the filter's.
        let (f, fe) = (
            r["fps"].as_f64().unwrap(),
            r["fps_with_encoder"].as_f64().unwrap(),
        );
        assert!(fe > 0.0 && fe < f, "{r}");
        let runs = r["per_sequence"].as_array().unwrap();
        assert_eq!(runs.len(), 1);
        assert_eq!(runs[0]["errors_m"].as_array().unwrap().len(), 6);
        let rmse = r["summary"]["mean"]["rmse"].as_f64().unwrap();
        // From the paper's local start (0.3 m, 17 degrees) the first frames
        // stay within a metre even with 64 particles.
        assert!(rmse.is_finite() && rmse < 1.0, "{r}");
    }
    assert!(text.contains("| OMCL_GT |"), "{text}");

    let (o, text) = bench(&[&["table2"], &small[..]].concat());
    assert!(o.status.success(), "{text}");
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("table2.json")).unwrap())
            .unwrap();
    let acc: Vec<f64> = rows
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["mean"]["accuracy"].as_f64().unwrap())
        .collect();
    // Grounded maps: every row is one of the 29 classes.
    for i in [0, 1, 3, 4] {
        assert!((0.5..=1.0).contains(&acc[i]), "{rows}");
    }
    // The ungrounded map's rows are raw pixel features, hundreds of them,
    // each a class of its own: a pixel counts only when its nearest row is
    // the very row its ray hits. Measured 0.10 with 662 rows present; a map
    // whose voxels held unrelated rows would score near 1/662. It stays
    // below the grounded LSeg map, whose rows are the classes themselves.
    let present = rows[2]["mean"]["classes_present"].as_f64().unwrap();
    assert!(present > 29.0, "{rows}");
    assert!(acc[2] > 0.05 && acc[2] > 20.0 / present, "{rows}");
    assert!(acc[2] < acc[1], "{rows}");
    // Exact labels on a map of the true labels agree with it more often
    // than bleeding ground-truth images with the map made of them
    // (OMCL_GT_exact vs OMCL_GT).
    assert!(acc[4] > acc[0], "{rows}");

    // --preset replaces a variant's features: the gt preset's bleeding
    // labels on the exact variant's map agree with it less than exact ones.
    let (o, text) = bench(
        &[
            &["table2", "--variants", "OMCL_GT_exact", "--preset", "gt"],
            &small[..],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{text}");
    let rows: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("table2.json")).unwrap())
            .unwrap();
    let bled = rows[0]["mean"]["accuracy"].as_f64().unwrap();
    assert!(
        (0.5..acc[4]).contains(&bled),
        "{bled} vs {}\n{rows}",
        acc[4]
    );
}

#[test]
fn overrides_reach_the_filter_and_bad_ones_are_refused() {
    let (o, text) = bench(&[
        "table1",
        "--show-config",
        "--set",
        "sharpen=5",
        "--set",
        "sensor.miss_score=0.25",
    ]);
    assert!(o.status.success(), "{text}");
    let v: serde_json::Value = serde_json::from_str(&String::from_utf8_lossy(&o.stdout)).unwrap();
    assert_eq!(v["sharpen"], 5.0);
    assert_eq!(v["sensor"]["miss_score"], 0.25);
    let (o, text) = bench(&["table1", "--show-config", "--set", "sensor.nope=1"]);
    assert!(!o.status.success());
    assert!(text.contains("no parameter \"sensor.nope\""), "{text}");
    let (o, text) = bench(&["table1", "--show-config", "--set", "sharpen=\"x\""]);
    assert!(!o.status.success());
    assert!(text.contains("invalid"), "{text}");
    // Each experiment shows the filter it starts from: the 6-DoF block's
    // has full motion noise and two layers, which `--set` can turn off;
    // table4's is the street filter; the indoor tables have one layer.
    let config = |args: &[&str]| -> serde_json::Value {
        let (o, text) = bench(args);
        assert!(o.status.success(), "{text}");
        serde_json::from_str(&String::from_utf8_lossy(&o.stdout)).unwrap()
    };
    let v = config(&["table1-sixdof", "--show-config"]);
    assert_eq!(v["motion"]["mode"], "Full", "{v}");
    assert_eq!(v["anneal"]["layers"], 2, "{v}");
    assert_eq!(v["anneal"]["expand"], 16, "{v}");
    assert_eq!(v["sampling"]["rays"], 4096, "{v}");
    assert_eq!(v["sharpen"], 240.0, "{v}");
    let v = config(&["table1-sixdof", "--show-config", "--rays", "512"]);
    assert_eq!(v["sampling"]["rays"], 512, "{v}");
    let v = config(&[
        "table1-sixdof",
        "--show-config",
        "--set",
        "anneal=null",
        "--set",
        "sixdof.height_m=0.3",
    ]);
    assert!(v["anneal"].is_null(), "{v}");
    // A parameter the filter would refuse is refused at `--set`, by name,
    // before any map is built.
    for (set, name) in [
        ("anneal.expand=0", "anneal.expand"),
        ("sharpen=-1", "sharpen"),
        ("sensor.miss_score=-0.5", "sensor.miss_score"),
    ] {
        let out = tempfile::tempdir().unwrap();
        let dir = out.path().join("never");
        let (o, text) = bench(&[
            "table1-sixdof",
            "--sequences",
            "1",
            "--set",
            set,
            "-o",
            dir.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{text}");
        assert!(
            text.contains("the filter would refuse") && text.contains(name),
            "{text}"
        );
        assert!(!dir.exists());
    }
    // So is a 2-D parameter of the block (the height of the bases and
    // tops). A height refused only once the map's ceiling is known
    // (taller than half the room) is refused by name too, and the folder
    // the run made is gone again.
    let out = tempfile::tempdir().unwrap();
    let dir = out.path().join("never");
    for (skirt, why) in [("0", "> 0 m"), ("1.3", "half the window")] {
        let set = format!("two_d.skirt={skirt}");
        let (o, text) = bench(&[
            "table1-floorplan",
            "--sequences",
            "1",
            "--frames",
            "5",
            "--variants",
            "OMCL_GT",
            "--set",
            &set,
            "-o",
            dir.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{text}");
        assert!(text.contains("two_d.skirt") && text.contains(why), "{text}");
        assert!(!dir.exists());
    }
    // Any experiment: Table IV without its trajectory files fails by name
    // and leaves no folder; a folder that was there before stays.
    let missing = out.path().join("no-such-trajectories");
    for existed in [false, true] {
        if existed {
            std::fs::create_dir(&dir).unwrap();
        }
        let (o, text) = bench(&[
            "table4",
            "--sequences",
            "1",
            "--trajectories",
            missing.to_str().unwrap(),
            "-o",
            dir.to_str().unwrap(),
        ]);
        assert!(!o.status.success(), "{text}");
        assert!(text.contains("KITTI_00_gt.txt"), "{text}");
        assert_eq!(dir.exists(), existed);
    }
    let v = config(&["table4", "--show-config"]);
    assert_eq!(v["motion"]["mode"], "Road", "{v}");
    assert_eq!(v["sampling"]["rays"], 4096, "{v}");
    let v = config(&["table1", "--show-config"]);
    assert!(
        v["anneal"].is_null() && v["motion"]["mode"] == "Planar",
        "{v}"
    );
    assert_eq!(v["sampling"]["rays"], 2048, "{v}");
    assert_eq!(v["sharpen"], 80.0, "{v}");
    // The 2-D block's own filter: more pixels, a sharper exponent, a
    // wider estimate.
    let v = config(&["table1-floorplan", "--show-config"]);
    assert_eq!(v["sampling"]["rays"], 8192, "{v}");
    assert_eq!(v["sharpen"], 240.0, "{v}");
    assert_eq!(v["estimate"]["radius"], 0.5, "{v}");
    assert_eq!(v["sampling"]["map_strata"], true, "{v}");
    assert!(v["anneal"].is_null(), "{v}");
    // Its point-cloud row stratifies over every row of the plan, unless
    // --set gives it the block's strata.
    let (o, text) = bench(&["table1-floorplan", "--show-config"]);
    assert!(o.status.success(), "{text}");
    let note = "OMCL_Open_LSeg, has its own";
    assert!(
        text.contains(note) && text.contains("over every row of the plan"),
        "{text}"
    );
    let (o, text) = bench(&[
        "table1-floorplan",
        "--show-config",
        "--set",
        "sampling.map_strata=false",
    ]);
    assert!(o.status.success() && !text.contains(note), "{text}");
}

/// Table V and both ablations in one call (maps shared), on a tiny
/// benchmark: one combined report, every JSON table with its cells and
/// values in range, every figure; the floor plan's band set for
/// table5-floorplan, which its heading gives.
#[test]
fn table5_and_ablations_write_tables_and_figures() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let (o, text) = bench(&[
        "table5",
        "table5-floorplan",
        "particles-rays",
        "sampling",
        "--sequences",
        "1",
        "--ablation-sequences",
        "1",
        "--frames",
        "8",
        "--map-frames",
        "20",
        "--particles",
        "64",
        "--starts",
        "1",
        "--max-steps",
        "4",
        "--set",
        "plan.band_max=1.5",
        "-o",
        out,
    ]);
    assert!(o.status.success(), "{text}");
    let md = std::fs::read_to_string(dir.path().join("bench.md")).unwrap();
    for h in [
        "Table V",
        "Table V on the floor plan (2-D: x, y, yaw)",
        "horizontal errors; plans of the band 0.10 to 1.50 m)",
        "particles x rays",
        "ray sampling",
    ] {
        assert!(md.contains(h), "{h} missing in\n{md}");
    }
    for f in [
        "ablation_particles_ape.png",
        "ablation_particles_fps.svg",
        "ablation_sampling.png",
    ] {
        assert!(dir.path().join(f).exists(), "{f} missing\n{text}");
    }
    let json = |f: &str| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(f)).unwrap()).unwrap()
    };
    let cells = json("ablation_particles_rays.json");
    let cells = cells.as_array().unwrap();
    assert_eq!(cells.len(), 16);
    for c in cells {
        let (rmse, fps) = (c["rmse"].as_f64().unwrap(), c["fps"].as_f64().unwrap());
        assert!(rmse.is_finite() && rmse < 1.5 && fps > 0.0, "{c}");
    }
    // Every cell of the 4 x 4 grid once (speed itself is a benchmark's
    // business, not a test's).
    for n in [256u64, 512, 1024, 2048] {
        for r in [512u64, 1024, 2048, 4096] {
            let of = cells
                .iter()
                .filter(|c| c["particles"] == n && c["rays"] == r)
                .count();
            assert_eq!(of, 1, "{n} particles x {r} rays: {cells:?}");
        }
    }
    let sampling = json("ablation_sampling.json");
    let sampling = sampling.as_array().unwrap();
    assert_eq!(sampling.len(), 9);
    assert!(
        sampling
            .iter()
            .all(|c| c["rmse_mean"].as_f64().unwrap() < 1.5)
    );
    for f in ["table5.json", "table5_floorplan.json"] {
        let t5 = json(f);
        let t5 = t5.as_array().unwrap();
        assert_eq!(t5.len(), 2, "{f}: without and with a prompt");
        for (t, prompt) in t5.iter().zip([false, true]) {
            assert_eq!(t["prompt"], prompt);
            assert_eq!(t["rows"].as_array().unwrap().len(), 5, "{f}: 2 .. 0.1 m");
            assert_eq!(t["runs"].as_array().unwrap().len(), 1);
        }
    }
}

/// Table I's 2-D and 6-DoF blocks in one call on a tiny benchmark: each
/// writes its table as Markdown and JSON and Figure 4 per row, the 2-D
/// block's baselines included; every row runs to the end of its sequence
/// from the paper's local start and stays within a metre.
#[test]
fn table1_blocks_write_tables_and_figure4() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let (o, text) = bench(
        &[
            &[
                "table1-floorplan",
                "table1-sixdof",
                "--variants",
                "OMCL_GT,SeDAR*_GT",
                "--sequences",
                "1",
            ][..],
            &common::TINY_RUN,
            &["-o", out],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{text}");
    for (name, rows) in [
        ("table1_floorplan", vec!["OMCL_GT", "SeDAR*_GT"]),
        ("table1_6dof", vec!["OMCL_GT"]),
    ] {
        let md = std::fs::read_to_string(dir.path().join(format!("{name}.md"))).unwrap();
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join(format!("{name}.json"))).unwrap(),
        )
        .unwrap();
        let got: Vec<&str> = json
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["variant"].as_str().unwrap())
            .collect();
        assert_eq!(got, rows, "{name}");
        // Each block states the filter it ran: --particles and --rays
        // over its own defaults, each block's exponent, the 3-D block's
        // two layers.
        let filter = if name == "table1_6dof" {
            "Filter: 64 particles x 128 rays, likelihood exponent 240, 2 layer(s)"
        } else {
            "Filter: 64 particles x 128 sampled pixels a frame, likelihood exponent 240"
        };
        assert!(md.contains(filter), "{md}");
        for r in json.as_array().unwrap() {
            let runs = r["per_sequence"].as_array().unwrap();
            assert_eq!(runs[0]["errors_m"].as_array().unwrap().len(), 6, "{r}");
            let rmse = r["summary"]["mean"]["rmse"].as_f64().unwrap();
            assert!(rmse.is_finite() && rmse < 1.0, "{name}: {r}");
            let v = r["variant"].as_str().unwrap();
            assert!(md.contains(&format!("| {v}, omcl |")), "{md}");
        }
        let tag = if name == "table1_floorplan" {
            "2d"
        } else {
            "6dof"
        };
        for v in rows {
            for ext in ["png", "svg"] {
                let v = v.replace('*', "");
                let f = dir.path().join(format!("figure4_{tag}_{v}.{ext}"));
                let len = std::fs::metadata(&f)
                    .unwrap_or_else(|e| panic!("{}: {e}\n{text}", f.display()))
                    .len();
                assert!(len > 1000, "{}: {len} bytes", f.display());
            }
        }
        // Every row's estimates and the ground truth as TUM files: `omcl
        // eval ape` (horizontal for the 2-D block) gives the row's RMSE
        // again; and what ran, in <name>.run.json.
        let traj = dir.path().join(format!("{name}_trajectories/seq_1000"));
        let truth = traj.join("groundtruth.txt");
        for r in json.as_array().unwrap() {
            let v = r["variant"].as_str().unwrap().replace('*', "");
            let mut args = vec![
                "eval".to_string(),
                "ape".into(),
                truth.to_str().unwrap().into(),
                traj.join(format!("{v}.txt")).to_str().unwrap().into(),
            ];
            if name == "table1_floorplan" {
                args.push("--horizontal".into());
            }
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let e = common::omcl(&args);
            assert!(e.ok(), "{}", e.text());
            let rmse = r["per_sequence"][0]["stats"]["rmse"].as_f64().unwrap();
            assert!(
                e.stdout.contains(&format!("rmse  {rmse:.6}"))
                    || e.stdout.contains(&format!("{rmse:.6}")),
                "{name} {v}: {rmse}\n{}",
                e.stdout
            );
        }
        let run: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(dir.path().join(format!("{name}.run.json"))).unwrap(),
        )
        .unwrap();
        assert_eq!(run["seeds"], serde_json::json!([1000]), "{run}");
        assert_eq!(run["spec"]["frames"], 6, "{run}");
        // Six frames are too few for the completion rule: not judged, as
        // `omcl localize` and `omcl eval` say (the benches had counted
        // such runs completed).
        assert!(
            md.contains("| 0/1 (1 not judged: under 16 frames) |"),
            "{md}"
        );
        for r in json.as_array().unwrap() {
            assert!(r["per_sequence"][0]["completed"].is_null(), "{r}");
        }
    }
    // The 2-D block again with its baseline only, into the same folder:
    // the earlier run's OMCL_GT figures go (they had stayed beside a
    // table without their row), said; no filter note for OMCL rows that
    // did not run. A renamed copy of a figure is no row's and stays.
    let mine = dir.path().join("figure4_2d_mine.png");
    std::fs::copy(dir.path().join("figure4_2d_OMCL_GT.png"), &mine).unwrap();
    let (o, text) = bench(
        &[
            &[
                "table1-floorplan",
                "--variants",
                "SeDAR*_GT",
                "--sequences",
                "1",
            ][..],
            &common::TINY_RUN,
            &["-o", out],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("its Figure 4 files of rows not run now are removed: figure4_2d_OMCL_GT.png, figure4_2d_OMCL_GT.svg"),
        "{text}"
    );
    assert!(!dir.path().join("figure4_2d_OMCL_GT.png").exists());
    assert!(mine.exists());
    assert!(dir.path().join("figure4_2d_SeDAR_GT.png").exists());
    assert!(dir.path().join("figure4_6dof_OMCL_GT.png").exists());
    let md = std::fs::read_to_string(dir.path().join("table1_floorplan.md")).unwrap();
    assert!(
        !md.contains("Filter:") && md.contains("The baselines sample"),
        "{md}"
    );
}

/// `--variants` that names no row of a Table I block, or no row at all, is
/// refused before anything runs, naming the block's rows; `--preset`
/// reaches the blocks' OMCL rows (it was silently ignored there before)
/// and the block says so.
#[test]
fn table1_blocks_check_variants_and_take_the_preset() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    for (args, want) in [
        (
            vec!["table1-floorplan", "--variants", "OMCL_GT_exact"],
            "names no row of table1-floorplan; its rows are OMCL_GT, OMCL_LSeg",
        ),
        (
            vec!["table1-sixdof", "--variants", "none"],
            "or `none` with --rgbd-odometry",
        ),
        (
            vec!["table1-sixdof", "--variants", "SeDAR*_GT"],
            "names no row of table1-sixdof",
        ),
        (
            vec!["table1-floorplan", "--variants", "OMCL_GT,OMCL_GTX"],
            "no row \"OMCL_GTX\"",
        ),
    ] {
        let mut args = args;
        args.extend(["-o", out]);
        let (o, text) = bench(&args);
        assert!(!o.status.success(), "{args:?}: {text}");
        assert!(text.contains(want), "{args:?}: {text}");
    }
    // Nothing was written by the refused runs.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    let run = |preset: Option<&str>| -> (String, Vec<f64>) {
        let sub = dir.path().join(preset.unwrap_or("own"));
        let mut args = vec![
            "table1-floorplan",
            "--variants",
            "OMCL_GT",
            "--sequences",
            "1",
            "--frames",
            "8",
            "--map-frames",
            "20",
            "--particles",
            "64",
            "--rays",
            "128",
            "-o",
            sub.to_str().unwrap(),
        ];
        if let Some(p) = preset {
            args.extend(["--preset", p]);
        }
        let (o, text) = bench(&args);
        assert!(o.status.success(), "{text}");
        let md = std::fs::read_to_string(sub.join("table1_floorplan.md")).unwrap();
        let json: serde_json::Value = serde_json::from_str(
            &std::fs::read_to_string(sub.join("table1_floorplan.json")).unwrap(),
        )
        .unwrap();
        let errors = json[0]["per_sequence"][0]["errors_m"]
            .as_array()
            .unwrap()
            .iter()
            .map(|e| e.as_f64().unwrap())
            .collect();
        (md, errors)
    };
    let (md_own, own) = run(None);
    let (md_exact, exact) = run(Some("exact"));
    assert!(!md_own.contains("--preset"), "{md_own}");
    assert!(
        md_exact.contains("localized with `exact` features instead of each variant's own"),
        "{md_exact}"
    );
    // Other features, another path: the preset was used.
    assert_eq!(own.len(), 8);
    assert_ne!(own, exact);
}

/// Table IV on a 20-frame street: the Markdown it prints is also written
/// as table4.md, beside table4.json (one run per odometry variant asked
/// for) and the path's figure.
#[test]
fn table4_writes_its_markdown_json_and_figure() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t4");
    let (o, text) = bench(&[
        "table4",
        "--street-frames",
        "20",
        "--sequences",
        "1",
        "--particles",
        "64",
        "--rays",
        "128",
        "--odometry",
        "noise",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{text}");
    let md = std::fs::read_to_string(out.join("table4.md")).unwrap();
    assert!(md.starts_with("## Table IV"), "{md}");
    assert!(
        String::from_utf8_lossy(&o.stdout).contains(md.trim()),
        "{text}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("table4.json")).unwrap()).unwrap();
    assert_eq!(json["runs"].as_array().unwrap().len(), 1, "{json}");
    assert!(out.join("table4_noise.png").exists());
}

/// A bench stopped (SIGTERM, as `timeout` or `scancel` send) before it
/// wrote anything leaves no empty `-o` folder it made (it had).
#[test]
fn a_bench_stopped_before_writing_leaves_no_empty_folder() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let mut child = Command::new(env!("CARGO_BIN_EXE_omcl"))
        .args([
            "bench",
            "table1-floorplan",
            "--sequences",
            "1",
            "--frames",
            "40",
            "-o",
        ])
        .arg(&out)
        .stderr(std::process::Stdio::piped())
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let t0 = std::time::Instant::now();
    while !out.exists() {
        assert!(
            child.try_wait().unwrap().is_none(),
            "ended before it made {}",
            out.display()
        );
        assert!(t0.elapsed().as_secs() < 120, "no folder in 120 s");
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let kill = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    use std::os::unix::process::ExitStatusExt;
    assert_eq!(o.status.signal(), Some(15), "{:?}", o.status);
    assert!(!out.exists(), "{} left behind", out.display());
}

/// Options of experiments a call does not run are refused before anything
/// is written, naming who takes them (they had been ignored silently).
#[test]
fn options_of_experiments_not_run_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    let o = out.to_str().unwrap();
    for (args, want) in [
        (
            vec!["table1-floorplan", "--jobs", "2"],
            "--jobs is an option of the planned experiments",
        ),
        (
            vec!["table1-sixdof", "--resume"],
            "--resume is an option of the planned experiments",
        ),
        (
            vec!["table1", "--street-frames", "10"],
            "--street-frames is an option of table4",
        ),
        (
            vec!["table1", "--starts", "2"],
            "--starts is an option of table5",
        ),
        (
            vec!["table5", "--ablation-sequences", "2"],
            "--ablation-sequences is an option of particles-rays and sampling",
        ),
        (
            vec!["table4", "--scenes-seeds", "1"],
            "--scenes-seeds is an option of sevenscenes",
        ),
        (
            vec!["table1-floorplan", "--set", "sixdof.height_m=0.3"],
            "--set sixdof.height_m=0.3 is table1-sixdof's",
        ),
        (
            vec!["table1", "--set", "plan.band_min=0.2"],
            "--set plan.band_min=0.2 is the floor plans'",
        ),
    ] {
        let (st, text) = bench(&[&args[..], &["-o", o]].concat());
        assert!(
            st.status.code() == Some(1) && text.contains(want) && text.contains("leave it out"),
            "{args:?}: {text}"
        );
        assert!(!out.exists(), "{args:?}: {} was made", out.display());
    }
    // table5-floorplan's plans take the block's band, checked before any
    // run.
    let (st, text) = bench(&["table5-floorplan", "--set", "plan.band_min=3", "-o", o]);
    assert!(
        st.status.code() == Some(1) && text.contains("height band [3, 2]"),
        "{text}"
    );
    assert!(!out.exists(), "{} was made", out.display());
    // table5-floorplan's 2-D pose takes planar motion noise only.
    let (st, text) = bench(&["table5-floorplan", "--set", "motion.mode=\"Full\"", "-o", o]);
    assert!(
        st.status.code() == Some(1) && text.contains("table5-floorplan estimates x, y and yaw"),
        "{text}"
    );
    assert!(!out.exists(), "{} was made", out.display());
}
