//! The simulator's class embeddings against the real CLIP text embeddings
//! in ../shared/data/clip_text (Detic, Apache-2.0).

mod common;

use common::shared;

use omcl::sim::embeddings::{SIM_CLASSES, build_table, dot};
use omcl::sim::files::{builtin_table, load_clip_bank, load_table, save_table};

#[test]
fn builtin_table_is_the_one_built_from_real_clip_rows() {
    let dir = shared("clip_text");
    let bank = load_clip_bank(&dir).unwrap();
    assert_eq!(bank.names.len(), 1203 + 80 + 365);
    for c in SIM_CLASSES {
        if let Some(src) = c.source {
            assert!(
                bank.find(src).is_some(),
                "{} ({src}) not in the real vocabularies",
                c.name
            );
        }
    }
    let built = build_table(&bank, SIM_CLASSES, 0).unwrap();
    let builtin = builtin_table().unwrap();
    assert_eq!(built.names, builtin.names);
    for (a, b) in built.rows.iter().zip(&builtin.rows) {
        assert!((a - b).abs() < 1e-6);
    }
    // A real pair as Detic's vectors have it (README: chair to armchair 0.958).
    let chair = bank.find("chair").unwrap();
    let armchair = bank.find("armchair").unwrap();
    let c = dot(
        &bank.rows[chair * 512..(chair + 1) * 512],
        &bank.rows[armchair * 512..(armchair + 1) * 512],
    );
    assert!((c - 0.958).abs() < 0.005, "{c}");
}

#[test]
fn drawn_rows_look_like_real_rows_to_the_rest_of_the_space() {
    let dir = shared("clip_text");
    let bank = load_clip_bank(&dir).unwrap();
    let t = builtin_table().unwrap();
    let n = 1203; // LVIS rows
    let mean_cos = |v: &[f32]| {
        (0..n)
            .map(|i| dot(v, &bank.rows[i * 512..(i + 1) * 512]) as f64)
            .sum::<f64>()
            / n as f64
    };
    // Real classes' mean cosine to all LVIS rows.
    let real: Vec<f64> = SIM_CLASSES
        .iter()
        .enumerate()
        .filter(|(_, c)| c.source.is_some())
        .map(|(i, _)| mean_cos(t.row(i)))
        .collect();
    let lo = real.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = real.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    for (i, c) in SIM_CLASSES.iter().enumerate() {
        if c.source.is_none() {
            let m = mean_cos(t.row(i));
            // Far from orthogonal (CLIP text space is a narrow cone) and within
            // the spread of real classes, widened by a tenth.
            assert!(
                m > lo - 0.1 && m < hi + 0.1,
                "{}: {m} not in [{lo}, {hi}]",
                c.name
            );
            assert!(m > 0.4, "{}: {m}", c.name);
        }
    }
}

#[test]
fn similarity_structure_of_the_table() {
    let t = builtin_table().unwrap();
    let id = |n: &str| t.index_of(n).unwrap();
    let cos = |a: &str, b: &str| t.cosine(id(a), id(b));
    // Furniture is closer to furniture than to bathroom fixtures, and
    // sinks to toilets than to sofas: structure a real CLIP space has.
    assert!(
        cos("chair", "sofa") > cos("chair", "toilet"),
        "{} {}",
        cos("chair", "sofa"),
        cos("chair", "toilet")
    );
    assert!(cos("sink", "toilet") > cos("sink", "sofa"));
    assert!(cos("car", "traffic sign") > 0.5);
    // Nothing is orthogonal, nothing is a duplicate.
    for i in 0..t.len() {
        for j in 0..i {
            let c = t.cosine(i, j);
            assert!(c > 0.3 && c < 0.99, "{} {} {c}", t.names[i], t.names[j]);
        }
    }
    // Prompts land on the rows the images use.
    assert_eq!(
        t.text_feature("TV Monitor").unwrap(),
        t.row(id("tv monitor"))
    );
}

#[test]
fn table_round_trips_through_files() {
    let t = builtin_table().unwrap();
    let dir = tempfile::tempdir().unwrap();
    save_table(dir.path(), &t).unwrap();
    let back = load_table(
        &dir.path().join("classes.txt"),
        &dir.path().join("embeddings.npy"),
    )
    .unwrap();
    assert_eq!(back.names, t.names);
    // Rows are renormalized on load: equal up to rounding.
    let diff = back
        .rows
        .iter()
        .zip(&t.rows)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    assert!(diff < 1e-6, "{diff}");
    std::fs::write(dir.path().join("classes.txt"), "a\nb\n").unwrap();
    let e = load_table(
        &dir.path().join("classes.txt"),
        &dir.path().join("embeddings.npy"),
    )
    .unwrap_err();
    assert!(e.to_string().contains("38 rows but 2 names"), "{e}");
}
