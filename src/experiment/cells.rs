//! The results of a sweep by table cell, as each experiment's report reads
//! them (`Ctx`), and the writers of the report's files.

use std::path::{Path, PathBuf};

use super::run::TrackingRow;
use super::task::{BenchPlan, Outcome, RunEntry, RunRecord, SweepError, TrackOutcome, Use};
use crate::plot;

/// One run's place in the manifest and its result, if valid.
pub(super) struct Slot<'a> {
    pub(super) entry: &'a RunEntry,
    pub(super) record: Option<RunRecord>,
}

pub(super) fn write_text(path: &Path, text: &str) -> Result<(), SweepError> {
    crate::io::atomic::write(path, text.as_bytes()).map_err(|source| SweepError::Io {
        path: path.to_path_buf(),
        source,
    })
}

pub(super) fn write_json(path: &Path, value: &impl serde::Serialize) -> Result<(), SweepError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| SweepError::Io {
        path: path.to_path_buf(),
        source: std::io::Error::other(e),
    })?;
    write_text(path, &text)
}

pub(super) fn plot_err(path: PathBuf) -> impl FnOnce(plot::PlotError) -> SweepError {
    move |source| SweepError::Plot { path, source }
}

pub(super) struct Ctx<'a> {
    pub(super) bench: &'a BenchPlan,
    pub(super) slots: &'a [Slot<'a>],
    pub(super) cache: Option<&'a Path>,
    pub(super) out: &'a Path,
}

impl Ctx<'_> {
    /// Results of the runs used by `u`, in manifest (seed) order.
    pub(super) fn records(&self, u: &Use) -> impl Iterator<Item = &RunRecord> {
        self.slots
            .iter()
            .filter(move |s| s.entry.uses.contains(u))
            .filter_map(|s| s.record.as_ref())
    }

    pub(super) fn tracks(&self, u: &Use) -> Vec<(&RunRecord, &TrackOutcome)> {
        self.records(u)
            .filter_map(|r| match &r.outcome {
                Outcome::Track(t) => Some((r, &**t)),
                _ => None,
            })
            .collect()
    }

    pub(super) fn tracking_row(&self, variant: &str, u: &Use) -> TrackingRow {
        let runs = self
            .tracks(u)
            .into_iter()
            .map(|(_, t)| t.result.clone())
            .collect();
        TrackingRow::new(variant, runs)
    }
}
