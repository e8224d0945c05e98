//! A synthetic benchmark sequence generated in memory: an indoor world, a
//! camera path through it, the paper's noisy odometry, and frames rendered
//! on demand (a 540 x 540 frame is 2 MB; a sequence is not kept rendered).

use crate::geometry::{Intrinsics, Pose};
use crate::map::LanguageMap;
use crate::sim::dataset::{IndoorDatasetConfig, IndoorScene, SimError, indoor_scene};
use crate::sim::embeddings::ClassEmbeddings;
use crate::sim::indoor::{INDOOR_CLASSES, WorldKind};
use crate::sim::paths;
use crate::sim::render::{self, Frame};

/// One sequence of the synthetic indoor benchmark.
pub struct SimSequence {
    pub config: IndoorDatasetConfig,
    pub scene: IndoorScene,
    /// The indoor classes' embeddings (rows in class-id order).
    pub table: ClassEmbeddings,
    pub intrinsics: Intrinsics,
    /// Odometry poses: ground truth with the paper's per-step noise (0.10 m
    /// and 6 degrees), no replayed drift, accumulated as real odometry is.
    pub odometry: Vec<Pose>,
}

impl SimSequence {
    /// Generates sequence `seed` with `frames` frames in the corridor
    /// apartment from the built-in class table (`table` must contain every
    /// indoor class).
    pub fn generate(seed: u64, frames: usize, table: &ClassEmbeddings) -> Result<Self, SimError> {
        Self::generate_in(WorldKind::Corridor, seed, frames, table)
    }

    /// Generates sequence `seed` with `frames` frames in a world of `kind`.
    pub fn generate_in(
        kind: WorldKind,
        seed: u64,
        frames: usize,
        table: &ClassEmbeddings,
    ) -> Result<Self, SimError> {
        let mut config = IndoorDatasetConfig::of_kind(kind, seed);
        config.path.frames = frames;
        let table = table.subset(INDOOR_CLASSES)?;
        let scene = indoor_scene(&config)?;
        let odometry = paths::odometry(&scene.poses, &[], &config.odometry);
        Ok(SimSequence {
            intrinsics: config.intrinsics(),
            config,
            scene,
            table,
            odometry,
        })
    }

    /// Ground-truth `world_from_camera` of every frame.
    pub fn poses(&self) -> &[Pose] {
        &self.scene.poses
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.scene.poses.len()
    }

    /// Whether the sequence has no frames.
    pub fn is_empty(&self) -> bool {
        self.scene.poses.is_empty()
    }

    /// Renders frame `i` (panics if `i >= len()`).
    pub fn render(&self, i: usize) -> Frame {
        render::render_frame(
            &self.scene.caster,
            &self.scene.world.voxels,
            &self.intrinsics,
            &self.scene.poses[i],
        )
    }

    /// The odometry increment `prev_camera_from_camera` fed to the filter at
    /// frame `i` (identity at frame 0).
    pub fn increment(&self, i: usize) -> Pose {
        if i == 0 {
            Pose::identity()
        } else {
            self.odometry[i - 1].inverse() * self.odometry[i]
        }
    }
}

/// What a localization run needs of a benchmark sequence, indoor
/// ([`SimSequence`]) or outdoor ([`super::table4::StreetSequence`]).
pub trait BenchSequence {
    /// Ground-truth `world_from_camera` of every frame.
    fn poses(&self) -> &[Pose];
    /// Renders frame `i` (panics if `i` is past the last frame).
    fn render(&self, i: usize) -> Frame;
    /// The odometry increment `prev_camera_from_camera` of frame `i`
    /// (identity at frame 0).
    fn increment(&self, i: usize) -> Pose;
    /// The camera.
    fn intrinsics(&self) -> Intrinsics;
    /// Class embeddings, rows in class-id order.
    fn table(&self) -> &ClassEmbeddings;
    /// Number of frames.
    fn frames(&self) -> usize {
        self.poses().len()
    }
    /// The map row most similar to each class of the table.
    fn class_rows(&self, map: &LanguageMap) -> Vec<u32> {
        let t = self.table();
        (0..t.len())
            .map(|c| {
                map.db()
                    .nearest(t.row(c))
                    .ok()
                    .flatten()
                    .map_or(0, |(r, _)| r as u32)
            })
            .collect()
    }
}

impl BenchSequence for SimSequence {
    fn poses(&self) -> &[Pose] {
        SimSequence::poses(self)
    }
    fn render(&self, i: usize) -> Frame {
        SimSequence::render(self, i)
    }
    fn increment(&self, i: usize) -> Pose {
        SimSequence::increment(self, i)
    }
    fn intrinsics(&self) -> Intrinsics {
        self.intrinsics
    }
    fn table(&self) -> &ClassEmbeddings {
        &self.table
    }
}
