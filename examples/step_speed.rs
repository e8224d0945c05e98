//! The 2-D (floor plan) and the 3-D filter step of Table I on the same
//! frames of one synthetic sequence, run after each other `REPS` times:
//! the frames' features are made before the first step, so the loop times
//! the filter alone, without the simulated encoder that `omcl bench
//! table1-floorplan`'s speed line runs beside it (that line is the
//! README's figure; this one is for measuring a change to the step, e.g.
//! an old and a new build of it interleaved).
//!
//! ```sh
//! cargo run --release --example step_speed -- [SEED] [FRAMES] [REPS] [RAYS] [2-D|3-D|2-D-nocast]
//! ```
//!
//! `2-D-nocast` (only when named) is the 2-D step with a caster that does
//! no work: every pixel of every particle "hits" the plan's first leaf at
//! once, so what remains is the rest of the step (the features stage, the
//! motion, the fans' set-up and the scoring, with the most cache-friendly
//! hits there are). It is the floor under any planar caster: the 2-D step
//! cannot be faster than it whatever the cast costs (its APE is
//! meaningless).
//!
//! Defaults: held-out sequence 1000, 40 frames, 2 repetitions, 2048
//! pixels drawn a frame, both modes; 1024 particles, the 2-D block's
//! filter (`FilterConfig::floor_plan`) with `RAYS` pixels, OMCL_GT (the
//! `gt` map and frames). Each line gives the mean step and its stages,
//! the horizontal APE RMSE, and a hash of the estimates: a change that
//! keeps every hit keeps the hash.

use omcl::experiment::features::{GridFeatures, SimFrameFeatures, builtin_table, feature_model};
use omcl::experiment::mapping::{BenchMap, MapParams, MapSource};
use omcl::experiment::sequence::SimSequence;
use omcl::experiment::table1_floorplan::{TwoDParams, open_session, plan_scene};
use omcl::geometry::Ray;
use omcl::map::FloorPlanParams;
use omcl::mcl::{FilterConfig, MotionMode, StepTimings};
use omcl::raycast::{Fan, Hit, RayCaster};
use omcl::session::SharedMap;
use omcl::sim::features::Preset;
use std::sync::Arc;
use std::time::Instant;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().collect();
    let usage = "usage: step_speed [SEED] [FRAMES] [REPS] [RAYS] [2-D|3-D|2-D-nocast]";
    let arg = |i: usize, d: u64| -> Result<u64, String> {
        a.get(i).map_or(Ok(d), |s| {
            s.parse()
                .map_err(|_| format!("argument {i}, {s:?}: not a whole number; {usage}"))
        })
    };
    let (seed, frames, reps, rays) = (
        arg(1, 1000)?,
        arg(2, 40)? as usize,
        arg(3, 2)?,
        arg(4, 2048)?,
    );
    let modes = ["2-D", "3-D", "2-D-nocast"];
    if a.len() > 6 || a.get(5).is_some_and(|m| !modes.contains(&m.as_str())) {
        return Err(usage.into());
    }
    let table = builtin_table()?;
    let seq = SimSequence::generate_in(Default::default(), seed, frames, &table)?;
    let map = BenchMap::build(
        &seq,
        MapSource::Features(Preset::Gt),
        &MapParams::default(),
        &|_| {},
    )?;
    let two_d = TwoDParams::default();
    let plan = plan_scene(&map, &FloorPlanParams::default(), &seq.table, &two_d)?;
    let mut filter = FilterConfig::floor_plan();
    filter.sampling.rays = rays as usize;
    filter.seed = seed;
    filter.motion.mode = MotionMode::Planar;
    let model = feature_model(&seq, Preset::Gt, 0x10c);
    let rendered: Vec<_> = (0..seq.len()).map(|i| seq.render(i)).collect();
    let t = Instant::now();
    let rows = omcl::experiment::run::class_rows(&seq, &map.map);
    let grid: Vec<GridFeatures> = rendered
        .iter()
        .enumerate()
        .map(|(i, f)| {
            GridFeatures::new(
                SimFrameFeatures::new(&model, Preset::Gt, f, i as u64, &rows),
                filter.sampling.stride,
            )
        })
        .collect();
    eprintln!("features made in {:.1} s", t.elapsed().as_secs_f64());
    let scenes = [
        (
            "2-D",
            SharedMap::from_parts("plan", plan.sighted_map.clone(), plan.sighted.clone())
                .with_strata(Some(plan.strata.clone())),
        ),
        (
            "3-D",
            SharedMap::from_parts("map", map.map.clone(), map.caster.clone()),
        ),
        (
            "2-D-nocast",
            SharedMap::from_parts(
                "plan",
                plan.sighted_map.clone(),
                Arc::new(NoCast(plan.sighted.len())),
            )
            .with_strata(Some(plan.strata.clone())),
        ),
    ];
    let scenes: Vec<_> = scenes.into_iter().map(|(n, s)| (n, Arc::new(s))).collect();
    for rep in 0..reps {
        for (name, scene) in &scenes {
            // Each mode when named; without a name, the two real ones.
            if a.get(5).map_or(*name == "2-D-nocast", |m| m != name) {
                continue;
            }
            let mut s = open_session(&seq, scene.clone(), filter, 1024)?;
            let (mut tim, mut wall, mut err2) = (StepTimings::default(), 0.0, 0.0);
            let mut hash = 0u64;
            for (i, frame) in grid.iter().enumerate() {
                let t = Instant::now();
                let r = s.step_by(&seq.increment(i), i as f64, frame)?.step;
                wall += t.elapsed().as_secs_f64();
                tim += r.timings;
                let d = r.estimate.translation.vector - seq.poses()[i].translation.vector;
                err2 += d.x * d.x + d.y * d.y;
                hash = hash.rotate_left(5) ^ r.estimate.translation.vector.x.to_bits();
            }
            let n = seq.len();
            println!(
                "rep {rep} {name}: step {:.2} ms ({}), horizontal RMSE {:.4} m, hash {hash:016x}",
                1e3 * wall / n as f64,
                tim.per_step_ms(n),
                (err2 / n as f64).sqrt()
            );
        }
    }
    Ok(())
}

/// A caster that does no work (`2-D-nocast`): every ray hits leaf 0 at
/// `t` 1, through the fan path as the planar caster's pixels go.
struct NoCast(usize);

impl RayCaster for NoCast {
    fn cast_serial(&self, _rays: &[Ray], hits: &mut [Hit]) {
        hits.fill(Hit { leaf: 0, t: 1.0 });
    }

    fn wants_column_order(&self) -> bool {
        true
    }

    fn cast_fans(
        &self,
        _origin: [f32; 3],
        _fans: &[Fan],
        _slopes: &[f32],
        _t_max: &[f32],
        hits: &mut [Hit],
    ) -> bool {
        hits.fill(Hit { leaf: 0, t: 1.0 });
        true
    }

    fn len(&self) -> usize {
        self.0
    }
}
