//! Ablation: APE and filter rate against the number of particles, for
//! several ray counts (a line plot of each).

use std::fmt::Write as _;

use super::cells::{Ctx, plot_err, write_json};
use super::run::TrackingRow;
use super::task::{Planner, SweepError, Task, Use};
use super::variant::Variant;
use crate::plot::{self, Axes, Series};

/// Particle counts of the particles x rays ablation.
pub const ABLATION_PARTICLES: [usize; 4] = [256, 512, 1024, 2048];
/// Ray counts of the particles x rays ablation.
pub const ABLATION_RAYS: [usize; 4] = [512, 1024, 2048, 4096];

impl Ctx<'_> {
    pub(super) fn particles_rays(&self) -> Result<String, SweepError> {
        let v = self.bench.ablation()?;
        let mut cells = Vec::new();
        for rays in ABLATION_RAYS {
            for particles in ABLATION_PARTICLES {
                let row = self.tracking_row(v.name, &Use::ParticlesRays { particles, rays });
                cells.push((particles, rays, row));
            }
        }
        let rmse = |r: &TrackingRow| r.summary.map_or(f64::NAN, |s| s.mean.rmse);
        let series = |f: &dyn Fn(&TrackingRow) -> f64| -> Vec<Series> {
            ABLATION_RAYS
                .iter()
                .map(|&rays| Series {
                    label: format!("{rays} rays"),
                    points: cells
                        .iter()
                        .filter(|c| c.1 == rays)
                        .map(|c| (c.0 as f64, f(&c.2)))
                        .collect(),
                })
                .collect()
        };
        for ext in ["png", "svg"] {
            let path = self.out.join(format!("ablation_particles_ape.{ext}"));
            plot::line_plot(
                &path,
                &Axes {
                    title: format!("APE RMSE against particles ({})", v.name),
                    x_label: "particles".into(),
                    y_label: "APE RMSE [m]".into(),
                    log_x: true,
                    log_y: false,
                },
                &series(&rmse),
            )
            .map_err(plot_err(path.clone()))?;
            let path = self.out.join(format!("ablation_particles_fps.{ext}"));
            plot::line_plot(
                &path,
                &Axes {
                    title: format!("Filter steps per second against particles ({})", v.name),
                    x_label: "particles".into(),
                    y_label: "steps/s".into(),
                    log_x: true,
                    log_y: true,
                },
                &series(&|r| r.fps),
            )
            .map_err(plot_err(path.clone()))?;
        }
        let json: Vec<_> = cells
            .iter()
            .map(|(n, rays, r)| serde_json::json!({"particles": n, "rays": rays, "rmse": rmse(r), "fps": r.fps, "completed": r.completed, "completed_cell": r.completed_cell, "sequences": r.per_sequence.len()}))
            .collect();
        write_json(&self.out.join("ablation_particles_rays.json"), &json)?;
        let mut s = format!(
            "## Ablation: particles x rays ({}, {} sequences; APE RMSE m / steps per second)\n\n| rays \\ particles |",
            v.name, self.bench.ablation_sequences
        );
        for n in ABLATION_PARTICLES {
            let _ = write!(s, " {n} |");
        }
        s += "\n|---|";
        s += &"---|".repeat(ABLATION_PARTICLES.len());
        s.push('\n');
        for rays in ABLATION_RAYS {
            let _ = write!(s, "| {rays} |");
            for c in cells.iter().filter(|c| c.1 == rays) {
                let _ = write!(s, " {:.3} / {:.1} |", rmse(&c.2), c.2.fps);
            }
            s.push('\n');
        }
        s.push('\n');
        Ok(s)
    }
}

/// Plans the particles x rays grid on the ablation sequences.
pub(super) fn plan(p: &Planner, v: &Variant, out: &mut Vec<(Task, Use)>) {
    for rays in ABLATION_RAYS {
        for particles in ABLATION_PARTICLES {
            let mut c = p.bench.filter;
            c.sampling.rays = rays;
            for s in p.bench.ablation_seeds() {
                let u = Use::ParticlesRays { particles, rays };
                out.push((p.track(s, v, c, particles), u));
            }
        }
    }
}
