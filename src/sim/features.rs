//! A feature model that errs the way open-vocabulary encoders do.
//!
//! Input per pixel: its class, the nearest different class within a band
//! around label boundaries and how far away it is, the incidence of the
//! ray on the surface and the depth ([`PixelContext`]). Output: a unit-norm
//! feature of the embedding table's dimension. Errors modelled:
//! - *confusion between similar classes*: a region (a square patch of the
//!   image, one class, one frame) is read as another class with a
//!   probability that grows at grazing views and with distance; the other
//!   class is drawn with probability proportional to
//!   `exp(cos(c, c') / temperature)`, so a chair becomes an armchair-like
//!   sofa far more often than a ceiling. "Stuff" classes (wall, floor,
//!   road...) are confused less than objects, as real encoders do;
//! - *boundary blur*: near a label boundary the feature blends towards the
//!   neighbouring class (encoders work at a coarser resolution and are
//!   upsampled);
//! - *per-pixel noise*: a random combination of directions from a fixed
//!   noise bank, cheap at 512-d.
//!
//! Every draw is a hash of (model seed, frame, pixel or region), so one
//! pixel's feature is the same whether computed alone
//! ([`FeatureModel::feature_at`], as the localizer does for its sampled
//! pixels) or as part of a whole image ([`FeatureModel::image_features`]).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::embeddings::{ClassEmbeddings, dot, normalize};
use super::render::{Frame, NO_LABEL};

/// Named parameter sets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Preset {
    /// The exact class embedding of every pixel's label: no error at all.
    Exact,
    /// Ground-truth semantic images as real datasets ship them: exact class
    /// embeddings, but labels near object boundaries bleed into the
    /// neighbour (annotations on a coarse mesh, rendering misregistration).
    /// Calibrated to the paper's Table II GT row.
    Gt,
    /// An LSeg-like encoder, calibrated to the paper's Table II LSeg row.
    LsegLike,
}

impl std::str::FromStr for Preset {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "exact" => Ok(Preset::Exact),
            "gt" => Ok(Preset::Gt),
            "lseg-like" | "lseg" => Ok(Preset::LsegLike),
            other => Err(format!(
                "unknown feature preset {other:?} (expected exact, gt or lseg-like)"
            )),
        }
    }
}

impl Preset {
    /// The preset's name as the CLI spells it.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Exact => "exact",
            Preset::Gt => "gt",
            Preset::LsegLike => "lseg-like",
        }
    }

    /// The preset's parameters.
    pub fn params(self) -> FeatureParams {
        match self {
            Preset::Exact => FeatureParams {
                noise: 0.0,
                boundary_px: 0.0,
                stuff_boundary_px: 0.0,
                boundary_mix: 0.0,
                boundary_jitter: 0.0,
                confusion_object: 0.0,
                confusion_stuff: 0.0,
                patch_fraction: 0.0,
                difficulty_spread: 0.0,
                temperature: 0.05,
                view_gain: 0.0,
                range_gain: 0.0,
                patch_px: 24,
            },
            // Calibrated with examples/sim_calibrate.rs (docs/sim.md): 87.0 /
            // 74.5 / 75.8 / 64.1 against Table II's GT row 86.8 / 79.0 / 79.0 / 67.5.
            Preset::Gt => FeatureParams {
                noise: 0.0,
                boundary_px: 5.0,
                stuff_boundary_px: 30.0,
                boundary_mix: 0.9,
                boundary_jitter: 0.6,
                confusion_object: 0.0,
                confusion_stuff: 0.0,
                patch_fraction: 0.0,
                difficulty_spread: 0.0,
                temperature: 0.05,
                view_gain: 0.0,
                range_gain: 0.0,
                patch_px: 8,
            },
            // Calibrated with examples/sim_calibrate.rs (docs/sim.md): 81.9 /
            // 58.7 / 52.6 / 46.9 against Table II's LSeg row 82.7 / 59.7 / 54.3 / 43.4.
            Preset::LsegLike => FeatureParams {
                noise: 0.5,
                boundary_px: 6.0,
                stuff_boundary_px: 0.0,
                boundary_mix: 0.9,
                boundary_jitter: 0.6,
                confusion_object: 0.65,
                confusion_stuff: 0.12,
                patch_fraction: 0.3,
                difficulty_spread: 0.6,
                temperature: 0.01,
                view_gain: 0.6,
                range_gain: 0.08,
                patch_px: 8,
            },
        }
    }
}

/// A point-cloud encoder (OpenScene-like 3-D distillation), for maps
/// built from point clouds: no view, range or image-boundary effects, but
/// misreads per region of space (a part of an object read as a similar
/// class, the same from every viewpoint) and per-point noise. Stuff is
/// misread far more often than by the image model: a point encoder sees
/// no image context, and OpenScene's map agrees less with LSeg's images
/// than LSeg's own map does. Calibrated on 2 benchmark sequences to the
/// paper's Table II row OMCL_Open\LSeg (62.9 / 38.3 / 42.9 / 27.0): 67.1 /
/// 27.3 / 30.6 / 22.0 (accuracy / precision / recall / IoU). Used through
/// [`FeatureModel::point_class`]; `patch_px` is unused, the region is
/// [`POINT_REGION_M`].
pub const OPENSCENE_LIKE: FeatureParams = FeatureParams {
    noise: 0.5,
    boundary_px: 0.0,
    stuff_boundary_px: 0.0,
    boundary_mix: 0.0,
    boundary_jitter: 0.0,
    confusion_object: 0.2,
    confusion_stuff: 0.4,
    patch_fraction: 0.7,
    difficulty_spread: 0.6,
    temperature: 0.01,
    view_gain: 0.0,
    range_gain: 0.0,
    patch_px: 0,
};

/// Edge of the cubic regions of space a point encoder's misreads are
/// shared over, metres.
pub const POINT_REGION_M: f64 = 0.4;

/// Parameters of the feature model.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FeatureParams {
    /// Norm of the per-pixel noise added to the unit embedding.
    pub noise: f32,
    /// Width of the band around label boundaries where features blur, pixels.
    pub boundary_px: f32,
    /// Width of the band where two stuff classes meet (wall-floor,
    /// wall-ceiling), pixels: annotations of room junctions are coarse.
    pub stuff_boundary_px: f32,
    /// Weight of the neighbour class right at the boundary (falls linearly
    /// to 0 at `boundary_px`).
    pub boundary_mix: f32,
    /// Per-pixel uniform jitter (full width) added to that weight.
    pub boundary_jitter: f32,
    /// Probability that an object class is misread in a frame.
    pub confusion_object: f32,
    /// The same for stuff classes (wall, floor, ceiling, road, ...).
    pub confusion_stuff: f32,
    /// Share of a misread class's patches that are misread (before the
    /// view and range growth).
    pub patch_fraction: f32,
    /// Log-normal spread of a per-class difficulty factor on the confusion.
    pub difficulty_spread: f32,
    /// Softmax temperature over cosine similarity when picking the class a
    /// region is confused with.
    pub temperature: f32,
    /// The misread share grows by `1 + view_gain * (1 - incidence)`.
    pub view_gain: f32,
    /// The misread share grows by `1 + range_gain * depth_m`.
    pub range_gain: f32,
    /// Side of the square regions confusion decisions are shared over, pixels.
    pub patch_px: u32,
}

/// What the model knows about one pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelContext {
    /// Class of the pixel ([`NO_LABEL`] where the ray missed).
    pub label: u16,
    /// Nearest different class within the boundary band and its Chebyshev
    /// distance in pixels (1 = adjacent).
    pub neighbour: Option<(u16, f32)>,
    /// |cos| between ray and surface normal.
    pub incidence: f32,
    /// z-depth, metres.
    pub depth: f32,
}

/// Where a frame's label edges are: every pixel's Chebyshev distance
/// (pixels, capped at 255) to the nearest labelled pixel with an
/// 8-neighbour of another label (or none). No pixel of another class than
/// a pixel's own lies closer to it than that: on a shortest 8-connected
/// path to one, the first pixel of another class than the start's (a miss
/// does not count) is such an edge pixel. Computed once per frame
/// ([`LabelEdges::new`], two passes over the image) for
/// [`FeatureModel::context_near`].
#[derive(Debug, Clone, PartialEq)]
pub struct LabelEdges {
    dist: Vec<u8>,
}

impl LabelEdges {
    /// The edges of `frame`'s labels.
    pub fn new(frame: &Frame) -> Self {
        let (w, h) = (frame.width as usize, frame.height as usize);
        let labels = &frame.labels;
        let edge = |i: usize| {
            let l = labels[i];
            if l == NO_LABEL {
                return false;
            }
            let (x, y) = (i % w, i / w);
            (y.saturating_sub(1)..=(y + 1).min(h - 1)).any(|yy| {
                (x.saturating_sub(1)..=(x + 1).min(w - 1)).any(|xx| labels[yy * w + xx] != l)
            })
        };
        LabelEdges {
            dist: crate::chebyshev::distance(w, h, edge),
        }
    }
}

/// The classes encoders see as background "stuff" rather than objects.
pub const STUFF_CLASSES: &[&str] = &[
    "wall",
    "floor",
    "ceiling",
    "road",
    "sidewalk",
    "building",
    "vegetation",
    "terrain",
];

const BANK: usize = 64;
const BANK_TERMS: usize = 6;

/// The feature model: a class embedding table plus error parameters.
#[derive(Debug, Clone)]
pub struct FeatureModel {
    pub params: FeatureParams,
    pub table: ClassEmbeddings,
    seed: u64,
    /// Per class, cumulative probabilities of the class it is confused with.
    confusion_cdf: Vec<Vec<f32>>,
    /// Per class, base confusion probability.
    confusion: Vec<f32>,
    /// Per class, whether it is a stuff class.
    stuff: Vec<bool>,
    /// Unit noise directions, `BANK * dim`.
    bank: Vec<f32>,
    /// Feature of a pixel that sees nothing: the normalized mean row.
    miss: Vec<f32>,
    /// `class_cos[a * k + c]`: cosine of class rows a and c.
    class_cos: Vec<f32>,
    /// `bank_cos[i * k + c]`: noise direction i against class row c.
    bank_cos: Vec<f32>,
}

impl FeatureModel {
    /// A model over `table` with `params`, deterministic in `seed`.
    pub fn new(table: ClassEmbeddings, params: FeatureParams, seed: u64) -> Self {
        let k = table.len();
        let dim = table.dim;
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xfea7_0000);
        let mut confusion = Vec::with_capacity(k);
        let mut stuff_of = Vec::with_capacity(k);
        for name in &table.names {
            let stuff = STUFF_CLASSES.iter().any(|s| s.eq_ignore_ascii_case(name));
            stuff_of.push(stuff);
            let z: f32 = StandardNormal.sample(&mut rng);
            let base = if stuff {
                params.confusion_stuff
            } else {
                params.confusion_object
            };
            confusion.push((base * (params.difficulty_spread * z).exp()).min(0.95));
        }
        let mut confusion_cdf = Vec::with_capacity(k);
        for c in 0..k {
            let mut w: Vec<f32> = (0..k)
                .map(|o| {
                    if o == c {
                        0.0
                    } else {
                        ((table.cosine(c, o) - 1.0) / params.temperature.max(1e-4)).exp()
                    }
                })
                .collect();
            let s: f32 = w.iter().sum();
            let mut acc = 0.0;
            for x in w.iter_mut() {
                acc += *x / s.max(f32::MIN_POSITIVE);
                *x = acc;
            }
            confusion_cdf.push(w);
        }
        let mut bank = vec![0.0f32; BANK * dim];
        for row in bank.chunks_mut(dim) {
            for x in row.iter_mut() {
                *x = StandardNormal.sample(&mut rng);
            }
            normalize(row);
        }
        let mut miss = vec![0.0f32; dim];
        for c in 0..k {
            for (m, x) in miss.iter_mut().zip(table.row(c)) {
                *m += x;
            }
        }
        if !normalize(&mut miss) {
            miss = vec![0.0; dim];
            if let Some(m) = miss.first_mut() {
                *m = 1.0;
            }
        }
        let class_cos: Vec<f32> = (0..k)
            .flat_map(|a| (0..k).map(move |c| (a, c)))
            .map(|(a, c)| dot(table.row(a), table.row(c)))
            .collect();
        let bank_cos: Vec<f32> = bank
            .chunks(dim)
            .flat_map(|b| (0..k).map(|c| dot(b, table.row(c))).collect::<Vec<_>>())
            .collect();
        FeatureModel {
            class_cos,
            bank_cos,
            params,
            table,
            seed,
            confusion_cdf,
            confusion,
            stuff: stuff_of,
            bank,
            miss,
        }
    }

    /// A model with a named preset.
    pub fn preset(table: ClassEmbeddings, preset: Preset, seed: u64) -> Self {
        Self::new(table, preset.params(), seed)
    }

    /// Feature dimension.
    pub fn dim(&self) -> usize {
        self.table.dim
    }

    /// The context of pixel `(u, v)` of a rendered frame: its class and the
    /// nearest other class within the boundary band (the first pixel of
    /// another class found ring by ring, each ring scanned row by row).
    pub fn context(&self, frame: &Frame, u: u32, v: u32) -> PixelContext {
        self.context_from(frame, u, v, 1)
    }

    /// [`FeatureModel::context`] with the frame's [`LabelEdges`], the same
    /// result: rings closer than the nearest label edge hold no other
    /// class and are not scanned, and a pixel farther than the band from
    /// every edge has no neighbour. (With a band of 30 pixels, ground
    /// truth's, a pixel inside a region scanned up to 3,720 pixels.)
    pub fn context_near(&self, frame: &Frame, edges: &LabelEdges, u: u32, v: u32) -> PixelContext {
        let first = edges.dist[frame.index(u, v)].max(1);
        self.context_from(frame, u, v, first as i64)
    }

    /// The boundary band's half-width, pixels.
    fn band(&self) -> i64 {
        self.params
            .boundary_px
            .max(self.params.stuff_boundary_px)
            .ceil() as i64
    }

    /// The context, its neighbour searched from ring `first` outwards.
    fn context_from(&self, frame: &Frame, u: u32, v: u32, first: i64) -> PixelContext {
        let i = frame.index(u, v);
        let label = frame.labels[i];
        let mut neighbour = None;
        'rings: for r in first..=self.band() {
            let (w, h) = (frame.width as i64, frame.height as i64);
            let (u, v) = (u as i64, v as i64);
            for dv in -r..=r {
                let step = if dv == -r || dv == r { 1 } else { 2 * r };
                let mut du = -r;
                while du <= r {
                    let (x, y) = (u + du, v + dv);
                    if x >= 0 && y >= 0 && x < w && y < h {
                        let l = frame.labels[(y * w + x) as usize];
                        if l != label && l != NO_LABEL {
                            neighbour = Some((l, r as f32));
                            break 'rings;
                        }
                    }
                    du += step;
                }
            }
        }
        PixelContext {
            label,
            neighbour,
            incidence: frame.incidence[i],
            depth: frame.depth[i],
        }
    }

    /// The class a pixel's feature is built around (after confusion and
    /// boundary bleed), with the weight of a second class it is blended
    /// with. Pure function of the seed, frame, pixel and context.
    fn classes_at(
        &self,
        frame: u64,
        u: u32,
        v: u32,
        ctx: &PixelContext,
    ) -> Option<(usize, Option<(usize, f32)>)> {
        if ctx.label == NO_LABEL || ctx.label as usize >= self.table.len() {
            return None;
        }
        let p = &self.params;
        let mut class = ctx.label as usize;
        let base = self.confusion[class];
        // Whether this class is misread in this frame at all: real encoders
        // misread an object in some views and not others.
        let active = base > 0.0 && unit(hash(&[self.seed, frame, class as u64, 0xac7])) < base;
        if active {
            // Region key: patch grid shifted per frame so patch edges move.
            let shift = hash(&[self.seed, frame, 0x5417]);
            let ps = p.patch_px.max(1) as u64;
            let pu = (u as u64 + shift % ps) / ps;
            let pv = (v as u64 + (shift >> 20) % ps) / ps;
            let h = hash(&[self.seed, frame, class as u64, pu, pv]);
            let r = unit(h);
            let grow = (1.0 + p.view_gain * (1.0 - ctx.incidence.clamp(0.0, 1.0)))
                * (1.0 + p.range_gain * ctx.depth.max(0.0));
            if r < (p.patch_fraction * grow).min(1.0) {
                // One confusion target per class and frame: an encoder that
                // misreads a class in a view misreads it the same way across
                // the view, which keeps the set of wrong classes per frame small.
                let r2 = unit(hash(&[self.seed, frame, class as u64, 0xc0f]));
                let cdf = &self.confusion_cdf[class];
                class = cdf.iter().position(|&c| r2 <= c).unwrap_or(cdf.len() - 1);
            }
        }
        let mut blend = None;
        if let Some((n, dist)) = ctx.neighbour
            && (n as usize) < self.table.len()
        {
            let band = if self.stuff[ctx.label as usize] && self.stuff[n as usize] {
                p.stuff_boundary_px.max(p.boundary_px)
            } else {
                p.boundary_px
            };
            let jitter =
                (unit(hash(&[self.seed, frame, u as u64, v as u64, 7])) - 0.5) * p.boundary_jitter;
            let w =
                (p.boundary_mix * (1.0 - (dist - 1.0) / band.max(1e-3)) + jitter).clamp(0.0, 1.0);
            if dist <= band && w > 0.0 {
                blend = Some((n as usize, w));
            }
        }
        Some((class, blend))
    }

    /// Writes the unit-norm feature of pixel `(u, v)` of frame `frame` into
    /// `out` (length [`FeatureModel::dim`]).
    pub fn feature_at(&self, frame: u64, u: u32, v: u32, ctx: &PixelContext, out: &mut [f32]) {
        let dim = self.dim();
        debug_assert_eq!(out.len(), dim);
        match self.classes_at(frame, u, v, ctx) {
            None => out.copy_from_slice(&self.miss),
            Some((c, blend)) => match blend {
                Some((n, w)) => {
                    for ((o, a), b) in out.iter_mut().zip(self.table.row(c)).zip(self.table.row(n))
                    {
                        *o = (1.0 - w) * a + w * b;
                    }
                }
                None => out.copy_from_slice(self.table.row(c)),
            },
        }
        if self.params.noise > 0.0 {
            self.noise_terms(self.pixel_noise_hash(frame, u, v), |idx, g| {
                for (o, b) in out.iter_mut().zip(&self.bank[idx * dim..(idx + 1) * dim]) {
                    *o += g * b;
                }
            });
        }
        if !normalize(out) {
            out.copy_from_slice(&self.miss);
        }
    }

    /// The class whose row is most similar to pixel `(u, v)`'s feature;
    /// `None` for a miss. Equal to the nearest table row of
    /// [`FeatureModel::feature_at`]'s feature (up to rounding at ties), but
    /// computed from class-by-class and noise-by-class cosine tables: `O(K)`
    /// instead of `O(K F)`, since the feature is a combination of at most two
    /// class rows and a few noise directions.
    pub fn predicted_class(&self, frame: u64, u: u32, v: u32, ctx: &PixelContext) -> Option<usize> {
        if ctx.label == NO_LABEL {
            return None;
        }
        let k = self.table.len();
        let (c, blend) = match self.classes_at(frame, u, v, ctx) {
            Some(x) => x,
            None => return Some(self.table.nearest(&self.miss).0),
        };
        let scores: Vec<f32> = match blend {
            Some((n, w)) => (0..k)
                .map(|o| (1.0 - w) * self.class_cos[c * k + o] + w * self.class_cos[n * k + o])
                .collect(),
            None => self.class_cos[c * k..(c + 1) * k].to_vec(),
        };
        self.best_with_noise(scores, self.pixel_noise_hash(frame, u, v))
    }

    /// The class whose row is most similar to a feature whose cosines to
    /// the class rows are `scores` before noise, once the noise terms drawn
    /// from hash `h` are added.
    fn best_with_noise(&self, mut scores: Vec<f32>, h: u64) -> Option<usize> {
        let k = self.table.len();
        if self.params.noise > 0.0 {
            self.noise_terms(h, |idx, g| {
                for (s, b) in scores
                    .iter_mut()
                    .zip(&self.bank_cos[idx * k..(idx + 1) * k])
                {
                    *s += g * b;
                }
            });
        }
        scores
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .map(|(i, _)| i)
    }

    /// The class a point encoder reads for a point of class `label` at `p`
    /// (world, metres): misread with probability `confusion * patch_fraction`
    /// per class and region of space ([`POINT_REGION_M`], one target class
    /// per region), then the nearest class row of that class's embedding
    /// plus the point's noise. `None` for [`NO_LABEL`] or an unknown class.
    /// A pure function of the seed, the point and its label.
    pub fn point_class(&self, p: [f64; 3], label: u16) -> Option<usize> {
        let k = self.table.len();
        if label == NO_LABEL || label as usize >= k {
            return None;
        }
        let mut class = label as usize;
        let cell = |x: f64| (x / POINT_REGION_M).floor() as i64 as u64;
        let region = [cell(p[0]), cell(p[1]), cell(p[2])];
        let h = hash(&[
            self.seed,
            class as u64,
            region[0],
            region[1],
            region[2],
            0x3d,
        ]);
        if unit(h) < (self.confusion[class] * self.params.patch_fraction).min(1.0) {
            let r2 = unit(splitmix(h ^ 0xc0f));
            let cdf = &self.confusion_cdf[class];
            class = cdf.iter().position(|&c| r2 <= c).unwrap_or(cdf.len() - 1);
        }
        // Noise keyed by the point's millimetre cell.
        let mm = |x: f64| (x * 1000.0).round() as i64 as u64;
        let h = hash(&[
            self.seed,
            mm(p[0]) ^ mm(p[2]).rotate_left(32),
            mm(p[1]),
            0x0153,
        ]);
        self.best_with_noise(self.class_cos[class * k..(class + 1) * k].to_vec(), h)
    }

    /// The hash the noise terms of pixel `(u, v)` of frame `frame` start from.
    fn pixel_noise_hash(&self, frame: u64, u: u32, v: u32) -> u64 {
        hash(&[self.seed, frame, u as u64, v as u64, 0x0153])
    }

    /// Calls `f(bank index, weight)` for each noise term drawn from hash `h`.
    fn noise_terms(&self, mut h: u64, mut f: impl FnMut(usize, f32)) {
        let scale = self.params.noise / (BANK_TERMS as f32).sqrt();
        for _ in 0..BANK_TERMS {
            h = splitmix(h);
            let idx = (h % BANK as u64) as usize;
            h = splitmix(h);
            f(idx, gaussian(h) * scale);
        }
    }

    /// Features of a whole frame at every `stride`-th pixel in each
    /// direction: `(height / stride) x (width / stride) x dim`, row-major
    /// (the layout of a per-frame `.npy`), and that grid's size.
    pub fn image_features(
        &self,
        frame_index: u64,
        frame: &Frame,
        stride: u32,
    ) -> (Vec<f32>, u32, u32) {
        use rayon::prelude::*;
        let s = stride.max(1);
        let (w, h) = (frame.width / s, frame.height / s);
        let dim = self.dim();
        let edges = LabelEdges::new(frame);
        let mut out = vec![0.0f32; w as usize * h as usize * dim];
        if out.is_empty() {
            // A stride larger than the frame: no pixel, no feature.
            return (out, w, h);
        }
        out.par_chunks_mut(w as usize * dim)
            .enumerate()
            .for_each(|(row, buf)| {
                let v = row as u32 * s + s / 2;
                for (col, px) in buf.chunks_mut(dim).enumerate() {
                    let u = col as u32 * s + s / 2;
                    let ctx = self.context_near(frame, &edges, u, v);
                    self.feature_at(frame_index, u, v, &ctx, px);
                }
            });
        (out, w, h)
    }
}

fn splitmix(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    x = (x ^ (x >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    x ^ (x >> 31)
}

/// A well-mixed 64-bit hash of a few words (SplitMix64 chained); random
/// access per pixel where a sequential generator cannot be used.
fn hash(words: &[u64]) -> u64 {
    words
        .iter()
        .fold(0x243f_6a88_85a3_08d3, |acc, &w| splitmix(acc ^ w))
}

/// Uniform in [0, 1) from the top 24 bits.
fn unit(h: u64) -> f32 {
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// A standard normal from a hash (Box-Muller on two 24-bit uniforms).
fn gaussian(h: u64) -> f32 {
    let a = ((h >> 40) as f32 + 0.5) / (1u64 << 24) as f32;
    let b = (((h >> 8) & 0xff_ffff) as f32) / (1u64 << 24) as f32;
    (-2.0 * a.ln()).sqrt() * (std::f32::consts::TAU * b).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> ClassEmbeddings {
        // wall, chair, sofa (chair and sofa similar), lamp (far).
        ClassEmbeddings::new(
            vec!["wall".into(), "chair".into(), "sofa".into(), "lamp".into()],
            4,
            vec![
                1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.9, 0.436, 0.0, 0.0, 0.0, 0.0, 1.0,
            ],
        )
        .unwrap()
    }

    fn frame(labels: Vec<u16>, w: u32) -> Frame {
        let n = labels.len();
        Frame {
            width: w,
            height: n as u32 / w,
            depth: vec![2.0; n],
            labels,
            leaves: vec![0; n],
            incidence: vec![1.0; n],
        }
    }

    /// The table-driven predicted class equals the nearest row of the full
    /// feature, on the built-in 512-d CLIP table with the noisiest preset,
    /// over boundaries, confusion patches and noise.
    #[test]
    fn predicted_class_matches_the_nearest_row_of_the_feature() {
        let t = crate::sim::files::builtin_table().unwrap();
        let k = t.len() as u16;
        let m = FeatureModel::preset(t, Preset::LsegLike, 5);
        let w = 96u32;
        let labels: Vec<u16> = (0..w * w)
            .map(|i| (((i % w) / 13 + (i / w) / 17 * 3) % k as u32) as u16)
            .collect();
        let f = frame(labels, w);
        let mut buf = vec![0.0; m.dim()];
        let (mut same, mut total) = (0, 0);
        for fi in 0..3u64 {
            for v in 0..w {
                for u in 0..w {
                    let ctx = m.context(&f, u, v);
                    m.feature_at(fi, u, v, &ctx, &mut buf);
                    let slow = m.table.nearest(&buf).0;
                    total += 1;
                    same += usize::from(m.predicted_class(fi, u, v, &ctx) == Some(slow));
                }
            }
        }
        // Only exact ties may differ by rounding.
        assert!(total - same <= total / 1000, "{same} of {total} agree");
    }

    #[test]
    fn exact_preset_returns_class_rows() {
        let m = FeatureModel::preset(table(), Preset::Exact, 1);
        let f = frame(vec![0, 1, 2, 3], 4);
        let mut out = vec![0.0; 4];
        for u in 0..4 {
            let ctx = m.context(&f, u, 0);
            m.feature_at(9, u, 0, &ctx, &mut out);
            assert_eq!(out.as_slice(), m.table.row(u as usize));
        }
    }

    #[test]
    fn confusion_goes_to_similar_classes() {
        // Chair pixels at full confusion: almost all become sofa, not lamp or wall.
        let mut p = Preset::Exact.params();
        p.confusion_object = 1.0;
        p.patch_fraction = 1.0;
        p.temperature = 0.05;
        p.patch_px = 1;
        let m = FeatureModel::new(table(), p, 3);
        let f = frame(vec![1; 64 * 64], 64);
        let mut counts = [0usize; 4];
        for v in 0..64 {
            for u in 0..64 {
                let ctx = m.context(&f, u, v);
                counts[m.predicted_class(0, u, v, &ctx).unwrap()] += 1;
            }
        }
        assert!(counts[2] > 3500, "{counts:?}");
        assert!(counts[0] + counts[3] < 40, "{counts:?}");
    }

    /// A point encoder without errors reads every point's own class; with
    /// full confusion, chair regions become sofa (the similar class), one
    /// target per region, so all points of a region agree; the misread
    /// rate is the configured one.
    #[test]
    fn point_class_errs_per_region_towards_similar_classes() {
        let exact = FeatureModel::preset(table(), Preset::Exact, 2);
        for l in 0..4u16 {
            assert_eq!(exact.point_class([0.3, -1.2, 0.7], l), Some(l as usize));
        }
        assert_eq!(exact.point_class([0.0; 3], NO_LABEL), None);
        assert_eq!(exact.point_class([0.0; 3], 4), None);
        let mut p = Preset::Exact.params();
        p.confusion_object = 1.0;
        p.patch_fraction = 1.0;
        p.temperature = 0.05;
        let m = FeatureModel::new(table(), p, 3);
        let mut counts = [0usize; 4];
        for i in 0..400 {
            let x = i as f64 * 0.013;
            counts[m.point_class([x, 0.1, 0.1], 1).unwrap()] += 1;
        }
        // Confusion is capped at 0.95: the rest stay chair.
        assert!(
            counts[2] > 340 && counts[1] + counts[2] == 400,
            "{counts:?}"
        );
        // Within one region every point reads the same class.
        let r = m.point_class([0.01, 0.01, 0.01], 1);
        assert!((0..30).all(|i| m.point_class([0.01 * i as f64, 0.02, 0.03], 1) == r));
        // Misread rate per class: confusion x patch_fraction (noise off),
        // within 4 sigma over 2000 regions.
        let t = crate::sim::files::builtin_table().unwrap();
        let m = FeatureModel::new(
            t,
            FeatureParams {
                noise: 0.0,
                ..OPENSCENE_LIKE
            },
            7,
        );
        for c in 0..m.table.len() {
            let n = 2000;
            let wrong = (0..n)
                .filter(|&i| {
                    let q = [(i % 50) as f64 * 0.41, (i / 50) as f64 * 0.43, 1.0];
                    m.point_class(q, c as u16) != Some(c)
                })
                .count() as f64
                / n as f64;
            let p = (m.confusion[c] * OPENSCENE_LIKE.patch_fraction) as f64;
            let sigma = (p * (1.0 - p) / n as f64).sqrt();
            assert!(
                (wrong - p).abs() <= 4.0 * sigma + 1e-9,
                "class {c}: {wrong} vs {p}"
            );
        }
    }

    #[test]
    fn boundary_band_blends_towards_the_neighbour() {
        let m = FeatureModel::preset(table(), Preset::Gt, 1);
        // Left half wall, right half lamp; 32 px wide.
        let labels: Vec<u16> = (0..32 * 4)
            .map(|i| if i % 32 < 16 { 0 } else { 3 })
            .collect();
        let f = frame(labels, 32);
        let ctx = m.context(&f, 15, 1);
        assert_eq!(ctx.neighbour, Some((3, 1.0)));
        let far = m.context(&f, 2, 1);
        // Found within the wide stuff band, but wall-lamp is not a stuff
        // junction: beyond the 5 px object band the feature stays exact.
        assert_eq!(far.neighbour, Some((3, 14.0)));
        let mut out = vec![0.0; 4];
        m.feature_at(0, 2, 1, &far, &mut out);
        assert_eq!(out.as_slice(), m.table.row(0));
        m.feature_at(0, 15, 1, &ctx, &mut out);
        assert!(out[3] > 0.3, "{out:?}");
    }

    #[test]
    fn per_pixel_and_whole_image_features_agree_and_are_unit_norm() {
        let m = FeatureModel::preset(table(), Preset::LsegLike, 5);
        let labels: Vec<u16> = (0..40 * 30).map(|i| ((i % 40) / 10) as u16).collect();
        let f = frame(labels, 40);
        let (img, w, h) = m.image_features(4, &f, 2);
        assert_eq!((w, h), (20, 15));
        let mut out = vec![0.0; 4];
        for (r, c) in [(0u32, 0u32), (7, 13), (14, 19)] {
            let (u, v) = (c * 2 + 1, r * 2 + 1);
            let ctx = m.context(&f, u, v);
            m.feature_at(4, u, v, &ctx, &mut out);
            let i = ((r * w + c) * 4) as usize;
            assert_eq!(&img[i..i + 4], out.as_slice());
            let n: f32 = out.iter().map(|x| x * x).sum();
            assert!((n - 1.0).abs() < 1e-5);
        }
        // Another frame index gives other noise.
        let (img2, _, _) = m.image_features(5, &f, 2);
        assert_ne!(img, img2);
    }

    /// The edge shortcut gives every pixel the context the full ring scan
    /// gives: regions of several sizes, misses (inside regions, at the
    /// image border, between regions), one-pixel specks, and the bands of
    /// ground truth (30 px), LSeg-like (6) and none.
    #[test]
    fn context_near_label_edges_equals_the_full_scan() {
        let t = crate::sim::files::builtin_table().unwrap();
        let (w, h) = (150u32, 110u32);
        let labels: Vec<u16> = (0..w * h)
            .map(|i| {
                let (u, v) = (i % w, i / w);
                if (u < 3 && v > 80) || (u > 30 && u < 36 && v > 20 && v < 26) {
                    NO_LABEL
                } else if u == 70 && v == 10 {
                    9
                } else if v < 70 {
                    (u / 75) as u16
                } else {
                    (2 + (u / 23 + v / 19) % 3) as u16
                }
            })
            .collect();
        let f = frame(labels, w);
        let edges = LabelEdges::new(&f);
        let mut far = 0;
        for preset in [Preset::Gt, Preset::LsegLike, Preset::Exact] {
            let m = FeatureModel::preset(t.clone(), preset, 5);
            for v in 0..h {
                for u in 0..w {
                    let (a, b) = (m.context(&f, u, v), m.context_near(&f, &edges, u, v));
                    assert_eq!(a, b, "{preset:?} ({u}, {v})");
                    far += usize::from(preset == Preset::Gt && a.neighbour.is_none());
                }
            }
        }
        // Some pixels lie farther than 30 px from another class.
        assert!(far > 0);
        // A frame of one class has no edges: every pixel is far.
        let one = frame(vec![4; 40 * 30], 40);
        assert!(LabelEdges::new(&one).dist.iter().all(|&d| d == 255));
        let m = FeatureModel::preset(t, Preset::Gt, 5);
        assert_eq!(
            m.context_near(&one, &LabelEdges::new(&one), 20, 15)
                .neighbour,
            None
        );
    }
}
