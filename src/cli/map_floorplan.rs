//! `omcl map floorplan`: project a language map to a floor plan (2-D grid,
//! features averaged along the vertical over a height band), written as a
//! versioned file and optionally a PNG.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;

use omcl::map::floorplan::{self, FloorPlan, FloorPlanParams};

#[derive(Debug, Args)]
pub struct FloorplanArgs {
    /// The 3-D language map (`.omcl`).
    pub map: PathBuf,
    /// Where to write the floor plan (safetensors, format `omcl-floor-plan`).
    #[arg(long, short)]
    pub out: PathBuf,
    /// Lower edge of the averaged height band, metres above the bottom of
    /// the map's lowest occupied layer (leaves the floor out).
    #[arg(long, default_value_t = FloorPlanParams::default().band_min)]
    pub band_min: f64,
    /// Upper edge of the band, metres above the same bottom as --band-min
    /// (leaves the ceiling out).
    #[arg(long, default_value_t = FloorPlanParams::default().band_max)]
    pub band_max: f64,
    /// Also write the plan as a PNG, one pixel a cell, +y up, free cells
    /// white, occupied cells coloured by feature row.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Replace --out or --png even when it is a file omcl did not write
    /// as such (an earlier plan or picture is replaced without it).
    #[arg(long)]
    pub force: bool,
}

pub fn run(a: &FloorplanArgs) -> anyhow::Result<()> {
    let mut outputs = vec![("--out", a.out.as_path())];
    outputs.extend(a.png.as_deref().map(|p| ("--png", p)));
    super::outputs::refuse_overlaps(&outputs, &[("the map", &a.map)])?;
    super::outputs::check_plan_out(&a.out, a.png.as_deref(), a.force)?;
    let map = omcl::map::load(&a.map)?;
    let params = FloorPlanParams {
        band_min: a.band_min,
        band_max: a.band_max,
    };
    let plan = FloorPlan::from_map(&map, &params)
        .with_context(|| format!("projecting {} to a floor plan", a.map.display()))?;
    // A band that takes in the floor's or the ceiling's layer makes every
    // cell under it a column (the plan's walls vanish among them): said,
    // as docs/table1.md says it (it had been taken without a word).
    // A voxel is in the band when its centre is (`FloorPlan::from_map`).
    let half = map.grid().resolution / 2.0;
    if a.band_min <= half {
        eprintln!(
            "note: --band-min {} m takes in the floor's layer (its voxels' centres are {half} m \
             above z = {:.3} m): every floor cell becomes a column of the plan; a --band-min \
             above {half} m keeps it out",
            a.band_min, plan.floor_z,
        );
    }
    // The top layer only for a band given: a default band above a flat
    // or outdoor map's top is no ceiling's.
    if let Some(ceiling) = plan.ceiling_height(&map)
        && a.band_max != FloorPlanParams::default().band_max
        && a.band_max >= ceiling + half
    {
        eprintln!(
            "note: --band-max {} m takes in the map's top layer ({:.2} m above the floor: a \
             ceiling indoors): every cell under it becomes a column of the plan; a \
             --band-max under {:.2} m keeps it out",
            a.band_max,
            ceiling + half,
            ceiling + half
        );
    }
    floorplan::save(&plan, &a.out)?;
    println!(
        "{} -> {}: {} columns of {} m, {} feature rows (from {} voxels, {} rows), band {}..{} m above z = {:.3} m",
        a.map.display(),
        a.out.display(),
        plan.len(),
        plan.resolution,
        plan.db().len(),
        map.len(),
        map.db().len(),
        params.band_min,
        params.band_max,
        plan.floor_z
    );
    if let Some(png) = &a.png {
        let (w, h, rgb) = plan.image();
        omcl::plot::write_picture_png(png, w, h, &rgb)
            .with_context(|| format!("writing {}", png.display()))?;
        println!("wrote {} ({w} x {h})", png.display());
    }
    Ok(())
}
