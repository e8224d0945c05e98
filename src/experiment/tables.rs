//! The paper's experiments as functions from a benchmark (sequences and
//! their maps) to result rows. Tables are plain data (serde) so the CLI
//! can write them as JSON and Markdown.

use std::sync::Arc;

use super::ExperimentError;
use super::mapping::{MapParams, MapSource, build_map};
use super::run::{RunResult, RunSpec, Start, run};
use super::sequence::SimSequence;
use crate::eval::localization::{SequenceSummary, summarize_sequences};
use crate::map::LanguageMap;
use crate::mcl::FilterConfig;
use crate::raycast::{EmbreeCaster, Packet, RayCaster};
use crate::sim::embeddings::ClassEmbeddings;
use crate::sim::features::{FeatureModel, Preset};

/// A map of a sequence's world with its ray caster.
pub struct BenchMap {
    pub source: MapSource,
    pub map: LanguageMap,
    pub caster: Arc<dyn RayCaster>,
}

impl BenchMap {
    /// Builds the map of `seq` from `source`.
    pub fn build(
        seq: &SimSequence,
        source: MapSource,
        params: &MapParams,
        progress: &(dyn Fn(usize) + Sync),
    ) -> Result<Self, ExperimentError> {
        let model = match source {
            MapSource::Features(p) => Some(feature_model(seq, p, 0x3a9)),
            MapSource::Labels => None,
        };
        let map = build_map(seq, source, params, model.as_ref(), progress)?;
        let caster = Arc::new(
            EmbreeCaster::new(map.grid().resolution as f32, &map.cells())?
                .with_packet(Packet::Single),
        );
        Ok(BenchMap {
            source,
            map,
            caster,
        })
    }
}

/// The feature model of `preset` for `seq` (`salt` separates the mapping
/// stream from the localization stream).
pub fn feature_model(seq: &SimSequence, preset: Preset, salt: u64) -> FeatureModel {
    FeatureModel::preset(
        seq.table.clone(),
        preset,
        seq.config.seed.wrapping_mul(0x9e37).wrapping_add(salt),
    )
}

/// One variant of Table I: which map and which features localize.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Variant {
    pub name: &'static str,
    pub map: MapSource,
    pub localize: Preset,
}

/// The variants of Table I reproduced here.
pub const TABLE1_VARIANTS: [Variant; 2] = [
    Variant {
        name: "OMCL_GT",
        map: MapSource::Labels,
        localize: Preset::Gt,
    },
    Variant {
        name: "OMCL_LSeg",
        map: MapSource::Features(Preset::LsegLike),
        localize: Preset::LsegLike,
    },
];

/// One variant's tracking results over the sequences.
#[derive(Debug, Clone, serde::Serialize)]
pub struct TrackingRow {
    pub variant: String,
    pub per_sequence: Vec<RunResult>,
    pub summary: Option<SequenceSummary>,
    pub completed: usize,
    /// Mean filter steps per second over all steps of all sequences.
    pub fps: f64,
}

impl TrackingRow {
    /// Gathers per-sequence results.
    pub fn new(variant: impl Into<String>, per_sequence: Vec<RunResult>) -> Self {
        let stats: Vec<_> = per_sequence.iter().map(|r| r.stats).collect();
        let steps: usize = per_sequence.iter().map(|r| r.step_seconds.len()).sum();
        let secs: f64 = per_sequence
            .iter()
            .flat_map(|r| r.step_seconds.iter())
            .sum();
        TrackingRow {
            variant: variant.into(),
            summary: summarize_sequences(&stats),
            completed: per_sequence.iter().filter(|r| r.completed).count(),
            fps: steps as f64 / secs.max(1e-12),
            per_sequence,
        }
    }
}

/// Tracks sequence `seq` in `map` from the paper's local start with
/// `filter`, `particles` and the features of `preset`.
pub fn track(
    seq: &SimSequence,
    map: &BenchMap,
    preset: Preset,
    filter: FilterConfig,
    particles: usize,
) -> Result<RunResult, ExperimentError> {
    let model = feature_model(seq, preset, 0x10c);
    let spec = RunSpec {
        filter,
        particles,
        start: Start::paper_local(),
        first: 0,
        frames: seq.len(),
        preset,
    };
    run(seq, &map.map, map.caster.clone(), &model, &spec)
}

/// The class table every benchmark uses: the simulator's built-in one.
pub fn builtin_table() -> Result<ClassEmbeddings, ExperimentError> {
    crate::sim::files::builtin_table()
        .map_err(|e| ExperimentError::Sim(crate::sim::dataset::SimError::Io(e)))
}
