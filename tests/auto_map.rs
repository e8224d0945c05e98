//! The ungrounded map (OMCL_auto_LSeg): raw per-pixel `lseg-like` features
//! through the map database with tau, no class in between. Its rows are
//! observed features and their blends, not the class table, and its voxels
//! still mostly point at their true class.

use omcl::experiment::features::builtin_table;
use omcl::experiment::mapping::BenchMap;
use omcl::experiment::{MapParams, MapSource, SimSequence};
use omcl::sim::features::Preset;

#[test]
fn the_ungrounded_map_holds_raw_features_that_still_name_their_class() {
    let table = builtin_table().unwrap();
    let seq = SimSequence::generate(1, 40, &table).unwrap();
    let params = MapParams {
        frames: 60,
        max_rows: 256,
        ..MapParams::default()
    };
    let map = BenchMap::build(&seq, MapSource::Auto(Preset::LsegLike), &params, &|_| {})
        .unwrap()
        .map;
    let db = map.db();
    let table = &seq.table;
    assert_eq!(db.dim(), table.dim);
    // Noisy raw features rarely lie within tau of each other: the database
    // fills to its cap, far more rows than the 29 classes.
    assert_eq!(db.len(), params.max_rows, "rows {}", db.len());
    // No row is a class row (the grounded and snapped maps' rows are).
    let near_class: Vec<f32> = (0..db.len()).map(|r| table.nearest(db.row(r)).1).collect();
    let exact = near_class.iter().filter(|&&s| s > 0.999).count();
    assert_eq!(exact, 0, "{exact} rows equal a class row");
    // Each voxel's feature names the class the world has there far more
    // often than chance (29 classes: a few per cent). Measured 0.324 with
    // these 256 rows: every feature snaps to the nearest of 256 noisy
    // observed features, which loses what the class would have kept.
    let world = &seq.scene.world.voxels;
    let (mut agree, mut known) = (0usize, 0usize);
    for (c, &r) in map.cells().iter().zip(map.rows()) {
        let centre = map.grid().center(*c);
        if let Some(l) = world.label_at(world.cell_of(&centre)) {
            known += 1;
            agree += usize::from(table.nearest(db.row(r as usize)).0 == l as usize);
        }
    }
    let acc = agree as f64 / known as f64;
    eprintln!(
        "{} voxels, {known} on a world voxel, nearest class right {:.3}",
        map.len(),
        acc
    );
    assert!(known > map.len() / 2, "{known} of {}", map.len());
    assert!(acc > 0.25, "nearest class right for {acc:.3} of the voxels");
}
