//! The variants the paper's tables compare: which map (built from which
//! features, grounded or not) and which features localize in it.

use super::mapping::MapSource;
use crate::sim::features::Preset;

/// One variant of Table I: which map and which features localize.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Variant {
    pub name: &'static str,
    pub map: MapSource,
    pub localize: Preset,
}

/// The variants of Table I reproduced here: the paper's OMCL_GT (ground-truth
/// semantic images for both mapping and localization, as the paper defines
/// it: the simulator's `gt` preset, exact class embeddings with the label
/// bleed of real ground-truth images near boundaries), OMCL_LSeg
/// (`lseg-like`), the ungrounded OMCL_auto_LSeg (the same map without
/// grounding on the class names) and OMCL_Open_LSeg (a map from the fused
/// point cloud labelled by an OpenScene-like point encoder, localized with
/// `lseg-like` images), plus OMCL_GT_exact (a map of the world's true
/// labels, as a semantic mesh gives them, localized with every pixel's true
/// class embedding: no error at all, the bound the sensor model reaches).
pub const TABLE1_VARIANTS: [Variant; 5] = [
    Variant {
        name: "OMCL_GT",
        map: MapSource::Features(Preset::Gt),
        localize: Preset::Gt,
    },
    Variant {
        name: "OMCL_LSeg",
        map: MapSource::Features(Preset::LsegLike),
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_auto_LSeg",
        map: MapSource::Auto(Preset::LsegLike),
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_Open_LSeg",
        map: MapSource::PointCloud,
        localize: Preset::LsegLike,
    },
    Variant {
        name: "OMCL_GT_exact",
        map: MapSource::Labels,
        localize: Preset::Exact,
    },
];

/// Whether `name` is in a comma-separated list of names (`None`: every
/// name is).
pub fn named_in(list: Option<&str>, name: &str) -> bool {
    list.is_none_or(|s| s.split(',').any(|x| x.trim() == name))
}
