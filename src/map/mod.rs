//! The Octree Language Map: voxel keys, the feature database, the sorted
//! leaves, integration of observations, grounding, queries, and the file
//! format.
mod container;
pub mod features;
pub mod file;
pub mod floorplan;
pub mod georef;
pub mod ground;
pub mod integrate;
pub mod key;
pub mod octree;
pub mod query;

pub use container::ContainerProblem;
pub use features::{FeatureDb, FeatureDbError};
pub use file::{MapFileError, load, save};
pub use floorplan::{FloorPlan, FloorPlanParams};
pub use georef::Georef;
pub use ground::{GroundingReport, classes_of_rows, ground};
pub use integrate::Integrator;
pub use key::{Cell, GridSpec};
pub use octree::{LanguageMap, MAX_RESOLUTION, MIN_RESOLUTION, MapError};
