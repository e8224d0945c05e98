//! `omcl demo`: the main job on the built-in synthetic world.
//!
//! Builds a synthetic apartment, integrates its labelled surfaces into an
//! Octree Language Map, writes and re-reads the map file, grounds it on a
//! prompt, and ray-traces a camera image with both ray casters.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, bail};
use clap::Args;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use omcl::geometry::{Intrinsics, camera_ray, level_camera};
use omcl::map::{self, FeatureDb, GridSpec, Integrator};
use omcl::raycast::{EmbreeCaster, RayCaster, ReferenceCaster};
use omcl::scene::{self, RoomsConfig};

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Folder for the demo's outputs (created if missing).
    #[arg(long, default_value = "demo-out")]
    pub out: PathBuf,
    /// Seed of the synthetic world.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// Voxel edge length, metres.
    #[arg(long, default_value_t = 0.05)]
    pub resolution: f64,
}

const CLASS_NAMES: [&str; 11] = [
    "floor",
    "wall",
    "ceiling",
    "table",
    "chair",
    "sofa",
    "bed",
    "cabinet",
    "shelving",
    "plant",
    "tv monitor",
];

/// Deterministic unit class features (stand-ins for text embeddings).
fn class_features(dim: usize, seed: u64) -> Vec<f32> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut rows = Vec::with_capacity(CLASS_NAMES.len() * dim);
    for _ in 0..CLASS_NAMES.len() {
        let v: Vec<f32> = (0..dim).map(|_| StandardNormal.sample(&mut rng)).collect();
        let n = v.iter().map(|x| x * x).sum::<f32>().sqrt();
        rows.extend(v.iter().map(|x| x / n));
    }
    rows
}

pub fn run(a: DemoArgs) -> anyhow::Result<()> {
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let t = Instant::now();
    let cfg = RoomsConfig {
        seed: a.seed,
        resolution: a.resolution,
        ..RoomsConfig::default()
    };
    let world = scene::rooms(&cfg);
    println!(
        "1/5 world     {} x {} m apartment, {} rooms, {} surface voxels at {} m ({:.2} s)",
        cfg.size_x,
        cfg.size_y,
        world.free_spots.len(),
        world.cells.len(),
        cfg.resolution,
        t.elapsed().as_secs_f64()
    );

    let t = Instant::now();
    let dim = 64;
    let table = FeatureDb::from_rows(dim, 0.02, class_features(dim, a.seed))?;
    let grid = GridSpec {
        resolution: cfg.resolution,
        origin: Vector3::zeros(),
    };
    let mut integ = Integrator::new(grid, table.clone())?;
    let pb = super::progress::bar(world.cells.len() as u64, "integrating");
    for (i, (c, &l)) in world.cells.iter().zip(&world.labels).enumerate() {
        integ.add_row(&grid.center(*c), l.min(CLASS_NAMES.len() as u32 - 1));
        if i % 65536 == 0 {
            pb.set_position(i as u64);
        }
    }
    pb.finish_and_clear();
    let m = integ.finish("demo-random-64", 0.02)?;
    println!(
        "2/5 map       {} leaves, {} feature rows ({:.2} s)",
        m.len(),
        m.db().len(),
        t.elapsed().as_secs_f64()
    );

    let path = a.out.join("demo.omcl");
    map::save(&m, &path)?;
    let back = map::load(&path)?;
    if back != m {
        bail!(
            "{} did not read back identical to what was written",
            path.display()
        );
    }
    let info = super::map::map_info(&path, &back, 5)?;
    println!("3/5 file      wrote and re-read {}:", path.display());
    for line in super::map::render_info(&info).lines() {
        println!("              {line}");
    }

    let mut grounded = back.clone();
    let prompt = ["floor", "wall", "table", "chair", "sofa"];
    let prompt_rows: Vec<f32> = prompt
        .iter()
        .flat_map(|w| {
            let i = CLASS_NAMES.iter().position(|n| n == w).unwrap_or(0);
            table.row(i).to_vec()
        })
        .collect();
    let prompts = FeatureDb::from_rows(dim, 0.02, prompt_rows)?;
    let rep = map::ground(&mut grounded, &prompts, 0.9)?;
    println!(
        "4/5 grounding on \"{}\": {} rows -> {}, kept {} voxels, dropped {}",
        prompt.join(", "),
        rep.old_rows,
        rep.new_rows,
        rep.kept,
        rep.dropped
    );

    let cells = back.cells();
    let res = cfg.resolution as f32;
    let t = Instant::now();
    let embree = EmbreeCaster::new(res, &cells)?;
    let build = t.elapsed();
    let reference = ReferenceCaster::new(res, &cells);
    let k = Intrinsics::from_hfov(540, 540, 90.0);
    let [x, y] = world.free_spots[0];
    let pose = level_camera(Vector3::new(x, y, 1.5), 0.4);
    let rays: Vec<_> = (0..k.height)
        .flat_map(|v| (0..k.width).map(move |u| (u, v)))
        .map(|(u, v)| camera_ray(&k, &pose, &grid.origin, u, v))
        .collect();
    let t = Instant::now();
    let he = embree.cast_vec(&rays);
    let te = t.elapsed();
    let t = Instant::now();
    let hr = reference.cast_vec(&rays);
    let tr = t.elapsed();
    let agree = he.iter().zip(&hr).filter(|(a, b)| a.leaf == b.leaf).count();
    let hits = he.iter().filter(|h| h.is_hit()).count();
    println!(
        "5/5 raycast   540x540 image: Embree {:.1} M rays/s (scene build {:.2} s), reference {:.2} M rays/s; \
         {hits} hits, casters agree on {:.3} % of rays",
        rays.len() as f64 / te.as_secs_f64() / 1e6,
        build.as_secs_f64(),
        rays.len() as f64 / tr.as_secs_f64() / 1e6,
        100.0 * agree as f64 / rays.len() as f64
    );
    // Map rows are formed in Morton order, not label order: name each row
    // by its most similar class feature.
    let row_class: Vec<usize> = (0..back.db().len())
        .map(|r| {
            table
                .nearest(back.db().row(r))
                .ok()
                .flatten()
                .map_or(0, |(c, _)| c)
        })
        .collect();
    // A coarse view of what the camera sees, by class initial.
    println!(
        "              camera view (class initials: f floor, w wall, ^ ceiling, t table, c chair, s sofa, ...):"
    );
    for v in (0..k.height).step_by(27) {
        let row: String = (0..k.width)
            .step_by(9)
            .map(|u| {
                let h = he[(v * k.width + u) as usize];
                if !h.is_hit() {
                    '.'
                } else {
                    let row = back.rows()[h.leaf as usize] as usize;
                    match CLASS_NAMES.get(row_class[row]).copied() {
                        Some("ceiling") => '^',
                        Some(name) => name.chars().next().unwrap_or('?'),
                        None => '?',
                    }
                }
            })
            .collect();
        println!("              {row}");
    }
    Ok(())
}
