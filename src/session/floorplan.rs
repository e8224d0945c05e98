//! Localizing on a floor plan: the 2-D scene a session runs in (Table I's
//! 2-D block, and `omcl localize --floorplan`).
//!
//! A [`PlanScene`] is a floor plan ([`crate::map::floorplan`]: the
//! language map's features averaged along the vertical) with what a camera
//! pixel sees of it in plan view: the sighted map ([`PlanScene::sighted_map`])
//! holds the plan's columns with their averaged rows, each column's own
//! floor and ceiling and its own base and top ([`PlanSight`]), and the text
//! features of "floor" and "ceiling" ([`EXIT_WORDS`]) for where a column
//! has no floor or ceiling of its own; the sighted caster
//! ([`crate::raycast::PlanarCaster::with_heights`]) follows each pixel's
//! ray over the plan to the first column it passes through, or to the
//! floor or ceiling where it leaves the plan's height window. The heights,
//! floors, ceilings, bases and tops come from the 3-D map the plan was
//! projected from (the plan file holds none of them), so a scene is made
//! from a 3-D map ([`PlanScene::from_map`]) or from a plan file with the
//! map it was made from ([`PlanScene::from_plan_of`]). A plan alone
//! ([`PlanScene::from_plan`]) gives infinitely tall columns, the view of
//! the SeDAR\* baseline.
//!
//! A session on a scene ([`super::SharedMap::floor_plan`]) runs the 3-D
//! filter's own pieces with planar motion and the camera held level at
//! the start's height ([`super::ground`]): x, y and yaw. The choices and
//! their measurements are in [`crate::experiment::table1_floorplan`].

use std::sync::Arc;

use crate::map::floorplan::FloorPlanError;
use crate::map::{FeatureDbError, FloorPlan, FloorPlanParams, LanguageMap, MapError};
use crate::raycast::PlanarCaster;

/// The words of the surfaces a floor plan leaves out below and above its
/// band, whose rows OMCL's 2-D map adds (floor exit, ceiling exit).
pub const EXIT_WORDS: [&str; 2] = ["floor", "ceiling"];

/// Errors making a [`PlanScene`].
#[derive(Debug, thiserror::Error)]
pub enum PlanSceneError {
    /// A parameter out of range, by name.
    #[error("{0}")]
    Config(String),
    /// A plan file that is not the projection of the map it came with.
    #[error("the floor plan is not the projection of the map: {0}")]
    NotProjectedFrom(String),
    #[error(transparent)]
    Plan(#[from] FloorPlanError),
    #[error(transparent)]
    Features(#[from] FeatureDbError),
    #[error(transparent)]
    Map(#[from] MapError),
}

/// What the sighted 2-D map adds to the plan's columns (see the module
/// documentation; tuned in [`crate::experiment::table1_floorplan`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlanSight {
    /// A ray leaving through the floor or ceiling hits that column's own
    /// floor or ceiling, the 3-D map's leaves below the band or in its top
    /// layer averaged ([`FloorPlan::surface_features`]), plus this weight
    /// times the word's text feature (the column's own average has unit
    /// length); the plan-wide word rows where a column has none. `None`:
    /// the word rows everywhere.
    pub surfaces: Option<f32>,
    /// Each column's own base and top, this many metres high: a pixel
    /// hitting a column within it of the band's bottom or of the ceiling
    /// scores that column's 3-D leaves there, averaged
    /// ([`FloorPlan::slab_features`]), instead of the band's average.
    /// `None`: the band's average at every height.
    pub skirt: Option<f32>,
}

impl Default for PlanSight {
    /// Half the word on each column's own floor and ceiling, bases and tops
    /// 0.10 m high (Table I's 2-D block).
    fn default() -> Self {
        PlanSight {
            surfaces: Some(0.5),
            skirt: Some(0.1),
        }
    }
}

impl PlanSight {
    /// Refuses, by name, a weight of the words that is negative or not
    /// finite and a height of the bases and tops that is not a finite
    /// number > 0. (A height that leaves the base and top no middle is
    /// refused when the map's ceiling is known, by [`PlanScene::from_map`].)
    pub fn validate(&self) -> Result<(), PlanSceneError> {
        if let Some(w) = self.surfaces.filter(|w| !(w.is_finite() && *w >= 0.0)) {
            return Err(PlanSceneError::Config(format!(
                "two_d.surfaces: the words' weight must be a finite number >= 0 (or null), got {w}"
            )));
        }
        if let Some(s) = self.skirt.filter(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(PlanSceneError::Config(format!(
                "two_d.skirt: the height must be a finite number > 0 m (or null), got {s}"
            )));
        }
        Ok(())
    }
}

/// How `plan` (read from a file) differs from `again` (its map projected
/// with its band), or `None` if it does not: grid, columns and rows
/// exactly, features to 1e-4 (another build may round the averages
/// differently).
fn differs(plan: &FloorPlan, again: &FloorPlan) -> Option<String> {
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * (1.0 + a.abs().max(b.abs()));
    if !close(plan.resolution, again.resolution) {
        return Some(format!(
            "the plan's cells are {} m, the map's {} m",
            plan.resolution, again.resolution
        ));
    }
    if !(close(plan.origin[0], again.origin[0])
        && close(plan.origin[1], again.origin[1])
        && close(plan.floor_z, again.floor_z))
    {
        return Some(format!(
            "the plan's origin and floor are ({:.3}, {:.3}) and {:.3} m, the map's ({:.3}, \
             {:.3}) and {:.3} m",
            plan.origin[0],
            plan.origin[1],
            plan.floor_z,
            again.origin[0],
            again.origin[1],
            again.floor_z
        ));
    }
    if plan.cells() != again.cells() {
        return Some(format!(
            "the plan has {} occupied columns, the map's band {} (or other ones)",
            plan.len(),
            again.len()
        ));
    }
    if plan.rows() != again.rows() || plan.db().len() != again.db().len() {
        return Some(format!(
            "the plan's columns use {} feature rows, the map's band gives {} (or assigns them \
             otherwise)",
            plan.db().len(),
            again.db().len()
        ));
    }
    let worst = (0..plan.db().len())
        .flat_map(|r| plan.db().row(r).iter().zip(again.db().row(r)))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    (worst > 1e-4).then(|| format!("the plan's features differ from the map's by up to {worst}"))
}

/// A floor plan with its one-layer map and planar casters.
pub struct PlanScene {
    pub plan: FloorPlan,
    /// The plan as a one-layer map (the baselines').
    pub map: LanguageMap,
    /// Columns as infinitely tall prisms (the baselines' plan).
    pub caster: Arc<PlanarCaster>,
    /// OMCL's 2-D map: the plan's columns and rows (layer 0), with
    /// [`PlanSight::surfaces`] each column's own floor and ceiling
    /// (layers 1 and 2, their rows admitted with the plan's tau), and the
    /// text features of "floor" and "ceiling" as two more rows, each held
    /// by one leaf of the first column (layers 3 and 4) for where a column
    /// has no floor or ceiling of its own; with [`PlanSight::skirt`],
    /// each occupied column's own base and top (layers 5 and 6, admitted
    /// with the plan's tau). The same as `map` for a plan made without its
    /// 3-D map.
    pub sighted_map: LanguageMap,
    /// Columns with their heights, rays ending on the floor and ceiling
    /// leaves of `sighted_map` (OMCL's 2-D sensor: what a pixel sees in
    /// plan view, see [`crate::raycast::PlanarCaster::with_heights`]). The
    /// same as `caster` for a plan made without its 3-D map.
    pub sighted: Arc<PlanarCaster>,
    /// Per row of `sighted_map`'s database, whether pixels are stratified
    /// over it ([`crate::mcl::Filter::with_strata`]): the plan's own rows
    /// and the floor and ceiling words, not the rows the sighted map
    /// derives from the 3-D map (each column's own floor, ceiling, base
    /// and top: blends near what those rows hold, whose
    /// clusters would be the pixels at boundaries, drawn as many times as a
    /// wall's).
    pub strata: Vec<bool>,
}

impl PlanScene {
    /// Projects a 3-D map to its floor plan; the sighted caster gets each
    /// column's extent, the window from the plan's band bottom to the
    /// map's ceiling, and the floor and ceiling rows `exit_rows` (unit
    /// text features of [`EXIT_WORDS`]; without them rays leaving the
    /// window miss) and, with [`PlanSight::surfaces`] (the words'
    /// weight), each column's own floor and ceiling, with
    /// [`PlanSight::skirt`] each column's own base and top.
    pub fn from_map(
        map: &LanguageMap,
        params: &FloorPlanParams,
        exit_rows: Option<[&[f32]; 2]>,
        sight: &PlanSight,
    ) -> Result<Self, PlanSceneError> {
        sight.validate()?;
        let plan = FloorPlan::from_map(map, params)?;
        Self::build(plan, map, exit_rows, sight)
    }

    /// The scene `omcl localize --floorplan` and `omcl serve --floorplan`
    /// localize in, with [`PlanSight::default`]: `plan` (a plan file's,
    /// checked against `map` by [`PlanScene::from_plan_of`]) or, without
    /// one, `map` projected with [`FloorPlanParams::default`].
    pub fn for_map(
        map: &LanguageMap,
        plan: Option<FloorPlan>,
        exit_rows: Option<[&[f32]; 2]>,
    ) -> Result<Self, PlanSceneError> {
        let sight = PlanSight::default();
        match plan {
            Some(plan) => Self::from_plan_of(plan, map, exit_rows, &sight),
            None => Self::from_map(map, &FloorPlanParams::default(), exit_rows, &sight),
        }
    }

    /// [`PlanScene::from_map`] for a plan read from a file (`omcl map
    /// floorplan`'s output): its band, columns and rows are used, and
    /// `map` (the 3-D map it was projected from) gives the heights,
    /// floors, ceilings, bases and tops the file does not hold. Refused
    /// with [`PlanSceneError::NotProjectedFrom`] when projecting `map`
    /// with the plan's band gives another grid or other columns.
    pub fn from_plan_of(
        plan: FloorPlan,
        map: &LanguageMap,
        exit_rows: Option<[&[f32]; 2]>,
        sight: &PlanSight,
    ) -> Result<Self, PlanSceneError> {
        sight.validate()?;
        if plan.db().dim() != map.db().dim() {
            return Err(PlanSceneError::NotProjectedFrom(format!(
                "the plan's features have dimension {}, the map's {}",
                plan.db().dim(),
                map.db().dim()
            )));
        }
        let again = FloorPlan::from_map(map, &plan.params)?;
        if let Some(why) = differs(&plan, &again) {
            return Err(PlanSceneError::NotProjectedFrom(why));
        }
        Self::build(plan, map, exit_rows, sight)
    }

    /// The scene of `plan`, projected from `map`.
    fn build(
        plan: FloorPlan,
        map: &LanguageMap,
        exit_rows: Option<[&[f32]; 2]>,
        sight: &PlanSight,
    ) -> Result<Self, PlanSceneError> {
        let params = plan.params;
        let surfaces = sight.surfaces;
        let extents = plan.column_extents(map);
        let ceiling = plan.ceiling_height(map).unwrap_or(f64::INFINITY);
        let own = surfaces.map(|_| plan.surface_features(map));
        let mut b = Self::from_plan(plan)?;
        // The sighted map: the plan's leaves on layer 0; with `surfaces`,
        // each column's own floor and ceiling on layers 1 and 2, their
        // rows admitted to the plan's database with its tau; the plan-wide
        // exit leaves on layers 3 and 4 of the first column (no columns
        // for the caster); with `skirt`, each column's own base and top on
        // layers 5 and 6.
        let mut leaves: Vec<(crate::map::Cell, u32)> = b
            .map
            .cells()
            .into_iter()
            .zip(b.map.rows().iter().copied())
            .collect();
        let mut db = b.plan.db().clone();
        for (side, list) in own.iter().flatten().enumerate() {
            for (c, sum) in list {
                // The column's own surface (unit) plus the word's row
                // times `surfaces`.
                let mut f = sum.clone();
                if let (Some(rows), Some(w)) = (exit_rows, surfaces) {
                    let n = crate::map::features::dot(&f, &f).sqrt();
                    if n > 0.0 {
                        for (a, b) in f.iter_mut().zip(rows[side]) {
                            *a = *a / n + w * b;
                        }
                    }
                }
                match db.admit(&f) {
                    Ok(row) => leaves.push(([c[0], c[1], 1 + side as i32], row as u32)),
                    Err(crate::map::FeatureDbError::Degenerate { .. }) => {}
                    Err(e) => return Err(e.into()),
                }
            }
        }
        // With `skirt`, each column's own base and top (layers 5 and 6).
        let skirt_z = sight.skirt.map(|h| {
            let h = h as f64;
            [params.band_min + h, ceiling - h]
        });
        if let (Some([z0, z1]), Some(h)) = (skirt_z, sight.skirt)
            && z0 >= z1
        {
            let h = if h < 1e4 {
                h.to_string()
            } else {
                format!("{h:e}")
            };
            return Err(PlanSceneError::Config(format!(
                "two_d.skirt: {h} m would make the base and top meet; the height must be \
                 below half the window from {:.2} to {:.2} m ({:.2} m)",
                params.band_min,
                ceiling,
                0.5 * (ceiling - params.band_min)
            )));
        }
        if let Some([z0, z1]) = skirt_z {
            let slabs = [
                b.plan.slab_features(map, params.band_min, z0),
                b.plan.slab_features(map, z1, ceiling),
            ];
            for (side, list) in slabs.iter().enumerate() {
                for (c, sum) in list {
                    match db.admit(sum) {
                        Ok(row) => leaves.push(([c[0], c[1], 5 + side as i32], row as u32)),
                        Err(crate::map::FeatureDbError::Degenerate { .. }) => {}
                        Err(e) => return Err(e.into()),
                    }
                }
            }
        }
        let k = db.len() as u32;
        let mut db_rows = db.rows().to_vec();
        if let (Some(rows), Some(&[i, j])) = (exit_rows, b.plan.cells().first()) {
            for (n, r) in rows.iter().enumerate() {
                db_rows.extend_from_slice(r);
                leaves.push(([i, j, 3 + n as i32], k + n as u32));
            }
        }
        let db = crate::map::FeatureDb::from_rows(b.plan.db().dim(), b.plan.db().tau(), db_rows)?;
        let own_rows = b.plan.db().len();
        b.strata = (0..db.len())
            .map(|r| r < own_rows || r >= k as usize)
            .collect();
        let sighted_map = LanguageMap::from_cells(*b.map.grid(), db, b.map.encoder(), leaves)?;
        // Each leaf's extent, the exits' and the columns' floor and ceiling
        // leaf indices, in the sighted map's own leaf order.
        let mut exits = [crate::raycast::Hit::MISS; 2];
        let mut sides: [Vec<([i32; 2], u32)>; 2] = [Vec::new(), Vec::new()];
        let mut skirts: [Vec<([i32; 2], u32)>; 2] = [Vec::new(), Vec::new()];
        let by_leaf: Vec<[f32; 2]> = sighted_map
            .cells()
            .iter()
            .enumerate()
            .map(|(leaf, c)| {
                match c[2] {
                    1 | 2 => sides[(c[2] - 1) as usize].push(([c[0], c[1]], leaf as u32)),
                    3 | 4 => exits[(c[2] - 3) as usize] = leaf as u32,
                    5 | 6 => skirts[(c[2] - 5) as usize].push(([c[0], c[1]], leaf as u32)),
                    _ => {}
                }
                b.plan
                    .cells()
                    .binary_search_by_key(&(c[1], c[0]), |p| (p[1], p[0]))
                    .ok()
                    .and_then(|n| extents.get(n).copied())
                    .unwrap_or([f32::NEG_INFINITY, f32::INFINITY])
            })
            .collect();
        let window = [params.band_min as f32, ceiling as f32];
        let caster = PlanarCaster::new(sighted_map.grid().resolution as f32, &sighted_map.cells());
        let caster = caster.with_heights(&by_leaf, window, exits);
        let caster = if surfaces.is_some() {
            caster.with_surfaces(&sides[0], &sides[1])
        } else {
            caster
        };
        b.sighted = Arc::new(match skirt_z {
            Some(z) => caster.with_skirts(&skirts[0], &skirts[1], z.map(|z| z as f32)),
            None => caster,
        });
        b.sighted_map = sighted_map;
        Ok(b)
    }

    /// A plan with its one-layer map and caster (columns infinitely tall:
    /// the plan alone holds no heights).
    pub fn from_plan(plan: FloorPlan) -> Result<Self, PlanSceneError> {
        let map = plan.to_language_map()?;
        let caster = Arc::new(PlanarCaster::new(
            map.grid().resolution as f32,
            &map.cells(),
        ));
        Ok(PlanScene {
            strata: vec![true; map.db().len()],
            plan,
            sighted_map: map.clone(),
            map,
            sighted: caster.clone(),
            caster,
        })
    }
}
