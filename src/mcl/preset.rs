//! The tuned filters by name, for callers that choose one by a word
//! (`omcl localize --filter`, `omcl serve`'s `CreateSession.filter`)
//! instead of setting its fields one by one.
//!
//! | name | filter | tuned on |
//! |---|---|---|
//! | `indoor` | [`FilterConfig::default`]: 2048 pixels, exponent 80, planar motion | Table I's 3-D map with planar motion (the paper's indoor setting) |
//! | `floor-plan` | [`FilterConfig::floor_plan`]: 8192 pixels, exponent 240, planar motion, estimate radius 0.5 m | Table I's 2-D block |
//! | `floor-plan-point-cloud` | [`FilterConfig::floor_plan_point_cloud`]: as `floor-plan` with the pixels stratified over every row of the plan, not only its own | the 2-D OMCL_Open_LSeg row (a map from a labelled point cloud, frames from an image encoder) |
//! | `six-dof` | [`FilterConfig::six_dof`]: full motion, two layers, the first on 16 copies, 4096 pixels, exponent 240 | Table I's 6-DoF block |
//! | `six-dof-point-cloud` | [`FilterConfig::six_dof_point_cloud`]: as `six-dof` with 512 pixels and the exponent 20 | the 6-DoF OMCL_Open_LSeg row (a map from a labelled point cloud, frames from an image encoder) |
//! | `street` | [`FilterConfig::street`]: road motion, 4096 pixels, two-pass likelihoods | Table IV (KITTI) |

use std::fmt;
use std::str::FromStr;

use super::filter::FilterConfig;

/// One of the tuned filters (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FilterPreset {
    Indoor,
    FloorPlan,
    FloorPlanPointCloud,
    SixDof,
    SixDofPointCloud,
    Street,
}

/// A filter name that names no [`FilterPreset`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown filter {given:?}: expected one of {}", FilterPreset::names())]
pub struct UnknownFilter {
    /// The name given, cut to its first [`MAX_QUOTED`] characters and
    /// `...` when longer.
    pub given: String,
}

impl FilterPreset {
    /// Every preset, in the order the help lists them.
    pub const ALL: [FilterPreset; 6] = [
        FilterPreset::Indoor,
        FilterPreset::FloorPlan,
        FilterPreset::FloorPlanPointCloud,
        FilterPreset::SixDof,
        FilterPreset::SixDofPointCloud,
        FilterPreset::Street,
    ];

    /// The preset's name, as [`FilterPreset::from_str`] reads it.
    pub fn name(self) -> &'static str {
        match self {
            FilterPreset::Indoor => "indoor",
            FilterPreset::FloorPlan => "floor-plan",
            FilterPreset::FloorPlanPointCloud => "floor-plan-point-cloud",
            FilterPreset::SixDof => "six-dof",
            FilterPreset::SixDofPointCloud => "six-dof-point-cloud",
            FilterPreset::Street => "street",
        }
    }

    /// Every name, comma-separated.
    pub fn names() -> String {
        FilterPreset::ALL.map(FilterPreset::name).join(", ")
    }

    /// The preset's filter (seed 0).
    pub fn config(self) -> FilterConfig {
        match self {
            FilterPreset::Indoor => FilterConfig::default(),
            FilterPreset::FloorPlan => FilterConfig::floor_plan(),
            FilterPreset::FloorPlanPointCloud => FilterConfig::floor_plan_point_cloud(),
            FilterPreset::SixDof => FilterConfig::six_dof(),
            FilterPreset::SixDofPointCloud => FilterConfig::six_dof_point_cloud(),
            FilterPreset::Street => FilterConfig::street(),
        }
    }
}

impl fmt::Display for FilterPreset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for FilterPreset {
    type Err = UnknownFilter;

    /// A preset by its name (exactly, as [`FilterPreset::name`] gives it).
    fn from_str(s: &str) -> Result<Self, UnknownFilter> {
        FilterPreset::ALL
            .into_iter()
            .find(|p| p.name() == s)
            .ok_or_else(|| UnknownFilter {
                given: quoted_prefix(s),
            })
    }
}

/// Longest part of an unknown name [`UnknownFilter`] repeats, in
/// characters: a name sent by a client may be of any length.
pub const MAX_QUOTED: usize = 64;

/// `s`, or its first [`MAX_QUOTED`] characters and `...`.
fn quoted_prefix(s: &str) -> String {
    match s.char_indices().nth(MAX_QUOTED) {
        Some((end, _)) => format!("{}...", &s[..end]),
        None => s.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mcl::{MotionMode, SIX_DOF_POINT_CLOUD_RAYS, SIX_DOF_RAYS};

    #[test]
    fn every_name_reads_back_and_unknown_names_list_the_known() {
        for p in FilterPreset::ALL {
            assert_eq!(p.name().parse::<FilterPreset>(), Ok(p));
            assert_eq!(p.to_string(), p.name());
        }
        let e = "6dof".parse::<FilterPreset>().unwrap_err();
        let text = e.to_string();
        assert!(text.contains("\"6dof\""), "{text}");
        for p in FilterPreset::ALL {
            assert!(text.contains(p.name()), "{text}");
        }
        assert!("Six-DoF".parse::<FilterPreset>().is_err());
        // A long name is quoted in part, whole characters only.
        let long = "é".repeat(10_000);
        let e = long.parse::<FilterPreset>().unwrap_err();
        assert_eq!(e.given, format!("{}...", "é".repeat(MAX_QUOTED)));
        assert!(e.to_string().len() < 400, "{e}");
    }

    #[test]
    fn presets_are_the_tuned_filters() {
        let six = FilterPreset::SixDof.config();
        assert_eq!(six.motion.mode, MotionMode::Full);
        assert_eq!(six.sampling.rays, SIX_DOF_RAYS);
        let anneal = six.anneal.expect("two layers");
        assert_eq!((anneal.layers, anneal.expand), (2, 16));
        let cloud = FilterPreset::SixDofPointCloud.config();
        assert_eq!(cloud.motion.mode, MotionMode::Full);
        assert_eq!(cloud.sampling.rays, SIX_DOF_POINT_CLOUD_RAYS);
        assert_eq!(cloud.sharpen, crate::mcl::SIX_DOF_POINT_CLOUD_SHARPEN);
        assert_eq!(cloud.anneal, six.anneal);
        assert_eq!(FilterPreset::Indoor.config(), FilterConfig::default());
        assert_eq!(FilterPreset::FloorPlan.config(), FilterConfig::floor_plan());
        // The point-cloud plan's filter is the block's but for its strata.
        let plan = FilterConfig::floor_plan();
        let cloud = FilterPreset::FloorPlanPointCloud.config();
        assert!(plan.sampling.map_strata && !cloud.sampling.map_strata);
        let mut same = cloud;
        same.sampling.map_strata = true;
        assert_eq!(same, plan);
        assert_eq!(FilterPreset::Street.config().motion.mode, MotionMode::Road);
    }
}
