//! How the 2-D experiments (Table I's 2-D block, `table5-floorplan`)
//! make their floor plans' scenes: which pixels OMCL's 2-D mode casts
//! ([`TwoDParams`]) and, with the band the plan is projected in,
//! [`PlanSettings`]. Apart from the experiments that use them, so that a
//! planned run's task can name them.

use super::ExperimentError;
use crate::map::FloorPlanParams;
use crate::session::floorplan::PlanSight;

/// How `table5-floorplan` projects a map to its floor plan and casts on
/// it: `omcl bench`'s `plan.*` and `two_d.*` (Table I's 2-D block's
/// settings; the defaults, as `omcl localize --floorplan` projects, unless
/// set).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct PlanSettings {
    pub plan: FloorPlanParams,
    pub two_d: TwoDParams,
}

/// Which pixels OMCL's 2-D mode casts, and how.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct TwoDParams {
    /// Largest elevation of a cast pixel's ray above or below the camera's
    /// horizontal plane, degrees (the camera is level in planar mode).
    pub max_elevation_deg: f64,
    /// Cast against the columns' heights between floor and ceiling, rays
    /// leaving through the floor or ceiling scored against those words
    /// ([`PlanScene::sighted`](crate::session::floorplan::PlanScene::sighted)); `false`: infinitely tall columns, rays
    /// that hit none miss (the block's model before 2026-11-24).
    pub heights: bool,
    /// Silence the pixels of
    /// [`OUT_OF_BAND_WORDS`](super::table1_floorplan::OUT_OF_BAND_WORDS)
    /// ([`InBandFeatures`](super::table1_floorplan::InBandFeatures)).
    pub silence: bool,
    /// With `silence`: `null` silences a pixel whose nearest class is out
    /// of band; a number, one whose cosine with such a word reaches it.
    pub silence_rho: Option<f32>,
    /// With `heights`: a ray leaving through the floor or ceiling hits that
    /// column's own floor or ceiling, the 3-D map's leaves below the band
    /// or in its top layer averaged ([`crate::map::FloorPlan::surface_features`]),
    /// plus this weight times the word's text feature (the column's own
    /// average has unit length); the plan-wide word rows where a column
    /// has none. `null`: the word rows everywhere (before 2026-11-25).
    pub surfaces: Option<f32>,
    /// With `heights`: each column's own base and top, this many metres
    /// high: a pixel hitting a column within it of the band's bottom or of
    /// the ceiling scores that column's 3-D leaves there, averaged
    /// ([`crate::map::FloorPlan::slab_features`]), instead of the band's average.
    /// `null`: the band's average at every height. Default 0.10 m (the
    /// documentation of [`super::table1_floorplan`] has the tuning).
    pub skirt: Option<f32>,
    /// With `heights`: stratify the pixels over the plan's own rows and
    /// the floor and ceiling words only ([`PlanScene::strata`](crate::session::floorplan::PlanScene::strata), the
    /// default since 2026-11-27; the documentation of
    /// [`super::table1_floorplan`] has the tuning); `false`: over every row of the sighted map (before).
    pub strata: bool,
}

impl Default for TwoDParams {
    fn default() -> Self {
        TwoDParams {
            max_elevation_deg: 90.0,
            heights: true,
            silence: false,
            silence_rho: None,
            surfaces: Some(0.5),
            skirt: Some(0.1),
            strata: true,
        }
    }
}

impl TwoDParams {
    /// Refuses, by name, a weight of the words that is negative or not
    /// finite and a height of the bases and tops that is not a finite
    /// number > 0 ([`PlanSight::validate`]).
    pub fn validate(&self) -> Result<(), ExperimentError> {
        Ok(self.sight().validate()?)
    }

    /// What the sighted 2-D map adds to the plan's columns.
    pub fn sight(&self) -> PlanSight {
        PlanSight {
            surfaces: self.surfaces,
            skirt: self.skirt,
        }
    }
}
