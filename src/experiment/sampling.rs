//! Ablation: the paper's stratified ray sampling against equal-per-cluster
//! sampling with duplicates and uniform sampling (a bar plot).

use std::fmt::Write as _;

use super::cells::{Ctx, plot_err, write_json};
use super::task::{Planner, SweepError, Task, Use};
use super::variant::Variant;
use crate::mcl::SamplingStrategy;
use crate::plot::{self, Axes, BarGroup};

/// Particle counts of the ray-sampling ablation.
pub const SAMPLING_PARTICLES: [usize; 3] = [256, 512, 1024];
/// The ray-sampling ablation's strategies, by name.
pub const SAMPLING_STRATEGIES: [(&str, SamplingStrategy); 3] = [
    ("stratified", SamplingStrategy::Stratified),
    ("equal", SamplingStrategy::EqualWithDuplicates),
    ("uniform", SamplingStrategy::Uniform),
];

impl Ctx<'_> {
    pub(super) fn sampling(&self) -> Result<String, SweepError> {
        let v = self.bench.ablation()?;
        let mut groups = Vec::new();
        let mut json = Vec::new();
        let mut s = format!(
            "## Ablation: ray sampling ({}, {} rays, {} sequences; APE RMSE m, completed)\n\n| particles | stratified | equal | uniform |\n|---|---|---|---|\n",
            v.name, self.bench.filter.sampling.rays, self.bench.ablation_sequences
        );
        for n in SAMPLING_PARTICLES {
            let mut bars = Vec::new();
            let _ = write!(s, "| {n} |");
            for (name, _) in SAMPLING_STRATEGIES {
                let row = self.tracking_row(
                    v.name,
                    &Use::Sampling {
                        particles: n,
                        strategy: name.into(),
                    },
                );
                let rmses: Vec<f64> = row.per_sequence.iter().map(|r| r.stats.rmse).collect();
                let (mean, std) = crate::eval::ErrorStats::from_errors(&rmses)
                    .map_or((f64::NAN, f64::NAN), |s| (s.mean, s.std));
                let _ = write!(s, " {mean:.3} ({}) |", row.completed_cell);
                bars.push((name.to_string(), mean, Some(std)));
                json.push(serde_json::json!({"particles": n, "strategy": name, "rmse_mean": mean, "rmse_std": std, "completed": row.completed, "completed_cell": row.completed_cell, "fps": row.fps}));
            }
            s.push('\n');
            groups.push(BarGroup {
                label: format!("{n} particles"),
                bars,
            });
        }
        for ext in ["png", "svg"] {
            let path = self.out.join(format!("ablation_sampling.{ext}"));
            plot::bar_plot(
                &path,
                &Axes {
                    title: format!("Ray sampling strategies ({})", v.name),
                    x_label: "particles".into(),
                    y_label: "APE RMSE [m]".into(),
                    log_x: false,
                    log_y: false,
                },
                &groups,
            )
            .map_err(plot_err(path.clone()))?;
        }
        write_json(&self.out.join("ablation_sampling.json"), &json)?;
        s.push('\n');
        Ok(s)
    }
}

/// Plans the sampling strategies on the ablation sequences.
pub(super) fn plan(p: &Planner, v: &Variant, out: &mut Vec<(Task, Use)>) {
    for particles in SAMPLING_PARTICLES {
        for (name, strategy) in SAMPLING_STRATEGIES {
            let mut c = p.bench.filter;
            c.sampling.strategy = strategy;
            for s in p.bench.ablation_seeds() {
                let u = Use::Sampling {
                    particles,
                    strategy: name.into(),
                };
                out.push((p.track(s, v, c, particles), u));
            }
        }
    }
}
