//! Top views of the indoor worlds: for each kind, the world of seed 1000
//! (the first held-out seed) seen from above, obstacles between 0.2 and
//! 2 m dark, with the benchmark's camera path (80 frames, path seed 1001,
//! as `omcl bench --frames 80` walks it). Writes
//! `docs/figures/world_<kind>.png`.
//!
//! ```sh
//! cargo run --release --example world_top_view
//! ```

use std::path::Path;

use omcl::plot::{FloorPlan, TrajectoryPanel, trajectory_plot};
use omcl::sim::dataset::IndoorDatasetConfig;
use omcl::sim::indoor::{WorldKind, generate};
use omcl::sim::paths::indoor_path;

fn main() -> anyhow::Result<()> {
    let out = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/figures");
    for kind in WorldKind::ALL {
        let mut cfg = IndoorDatasetConfig::of_kind(kind, 1000);
        cfg.path.frames = 80;
        let w = generate(&cfg.world);
        let v = &w.voxels;
        let floor = v
            .classes
            .iter()
            .position(|c| c == "floor")
            .map(|i| i as u16);
        let centres = v.cells.iter().zip(&v.labels).map(|(c, &l)| {
            let p = v.cell_centre(*c);
            ([p.x, p.y, p.z], Some(l) == floor)
        });
        let plan = FloorPlan::from_voxels(centres, v.resolution, (0.2, 2.0))
            .ok_or_else(|| anyhow::anyhow!("{kind}: empty world"))?;
        let xy: Vec<[f64; 2]> = indoor_path(&w.layout, &cfg.path)
            .iter()
            .map(|q| [q.translation.vector.x, q.translation.vector.y])
            .collect();
        let zeros = vec![0.0; xy.len()];
        let title = format!(
            "{kind}, seed 1000: {} rooms, 80-frame path",
            w.layout.rooms.len()
        );
        let path = out.join(format!("world_{kind}.png"));
        trajectory_plot(
            &path,
            &TrajectoryPanel {
                title: &title,
                plan: Some(&plan),
                gt_xy: &xy,
                est_xy: &xy,
                errors_m: &zeros,
            },
        )?;
        println!("wrote {}", path.display());
    }
    Ok(())
}
