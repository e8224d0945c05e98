//! The feature database (`Features_DB` in the paper): K unit-norm rows of
//! dimension F that are mutually more than a cosine distance `tau` apart.
//!
//! A feature is *admitted* (appended) only if its cosine distance
//! `d(a, b) = 1 - a.b / (|a||b|)` to every row exceeds `tau` (paper, eq. 1);
//! otherwise it is represented by its most similar row. An optional cap on
//! the number of rows bounds memory and per-feature cost when features are
//! noisy; past the cap every feature maps to its nearest row.

/// Errors building a database.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FeatureDbError {
    #[error("feature dimension must be at least 1")]
    ZeroDim,
    #[error("feature has dimension {got}, database has {expected}")]
    DimMismatch { expected: usize, got: usize },
    #[error("feature {index} is zero or not finite: it has no direction")]
    Degenerate { index: usize },
    #[error("tau must be a cosine distance in [0, 2], got {0}")]
    BadTau(f32),
}

/// Where [`FeatureDb::dots_and_norms`] reads `n` features of the
/// database's dimension F.
#[derive(Clone, Copy)]
pub enum Features<'a> {
    /// All of them, row-major `n x F`.
    Slice(&'a [f32]),
    /// `fill(j, buf)` writes feature `j` into a zeroed buffer of length F.
    Fill(&'a (dyn Fn(usize, &mut [f32]) + Sync)),
}

/// Normalizes `v` in place; `false` when it has no direction (zero or not
/// finite), in which case `v` is left unchanged.
pub fn normalize(v: &mut [f32]) -> bool {
    let n = v.iter().map(|x| x * x).sum::<f32>().sqrt();
    if !(n.is_finite() && n > 0.0) {
        return false;
    }
    v.iter_mut().for_each(|x| *x /= n);
    true
}

/// Dot product of two equally long slices.
#[inline]
pub fn dot(a: &[f32], b: &[f32]) -> f32 {
    // Four accumulators let the compiler vectorize without reassociation.
    let mut acc = [0.0f32; 8];
    let (ca, ra) = a.as_chunks::<8>();
    let (cb, rb) = b.as_chunks::<8>();
    for (x, y) in ca.iter().zip(cb) {
        for l in 0..8 {
            acc[l] += x[l] * y[l];
        }
    }
    let tail: f32 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    acc.iter().sum::<f32>() + tail
}

/// `dst = lhs rhs` for `lhs` (`m x n`, row-major) and `rhs` (`n x p`,
/// column-major), `dst` (`m x p`) row-major: `dst[i * p + c]` is row `i` of
/// `lhs` dotted with column `c` of `rhs`. On the calling thread (callers
/// parallelize over blocks of rows). faer's kernels (runtime-dispatched
/// AVX2 / AVX-512) multiply the narrow shapes here (`p` the database's 20
/// to 100 rows) without packing the wide operand, which is what
/// `matrixmultiply` spent half its time on: 1.8 to 1.9 times faster on
/// 18,225 x 512 features against 29 rows (docs/table1.md, "The features stage
/// through faer").
fn products(dst: &mut [f32], lhs: &[f32], rhs: &[f32], m: usize, n: usize, p: usize) {
    use faer::{Accum, MatMut, MatRef, Par, linalg::matmul::matmul};
    let a = MatRef::from_row_major_slice(lhs, m, n);
    let b = MatRef::from_column_major_slice(rhs, n, p);
    let c = MatMut::from_row_major_slice_mut(dst, m, p);
    matmul(c, Accum::Replace, a, b, 1.0f32, Par::Seq);
    clear_upper_registers();
}

/// Executes `vzeroupper` where the CPU has AVX. faer's x86 kernels are
/// assembly that returns with the upper halves of the vector registers in
/// use, and until they are cleared every SSE instruction of this thread
/// (the baseline x86-64 code the rest of omcl compiles to) pays for the
/// mixed state: the 2-D cast after the features stage took 34 ms a step
/// instead of 25 on the held-out sequence 1000 (docs/table1.md, "The features
/// stage through faer"). Compilers emit this instruction after their own
/// AVX code; assembly has to be followed by it.
fn clear_upper_registers() {
    #[cfg(target_arch = "x86_64")]
    if let Some(avx) = pulp::core_arch::x86::Avx::try_new() {
        avx._mm256_zeroupper();
    }
}

/// The feature database.
#[derive(Debug, Clone)]
pub struct FeatureDb {
    dim: usize,
    tau: f32,
    max_rows: Option<usize>,
    rows: Vec<f32>,
    /// The rows through a basis of their span, when it is narrower than
    /// they are many (made on first use; see [`Span`]).
    span: std::sync::OnceLock<Option<Span>>,
}

impl PartialEq for FeatureDb {
    /// The same dimension, threshold, cap and rows (the cached span
    /// follows from them).
    fn eq(&self, other: &Self) -> bool {
        (self.dim, self.tau, self.max_rows) == (other.dim, other.tau, other.max_rows)
            && self.rows == other.rows
    }
}

/// The rows `R` (K x F) written as `C^T Q^T`: `Q` an orthonormal basis of
/// their span (F x r), `C` their coordinates in it (r x K). A feature's
/// products with all rows are then `C^T (Q^T f)`: F r + r K
/// multiply-adds instead of F K. Worth it when the rows are linearly
/// dependent: a floor plan's rows are averages of its 3-D map's rows (the
/// synthetic benchmark's OMCL_GT plan: 56 rows of rank 23), so their span
/// is no wider than the map's.
///
/// From the eigendecomposition of the smaller Gram matrix (in f64): with
/// no more rows than dimensions `R R^T = V L V^T` (K x K), `Q = R^T V_r
/// L_r^(-1/2)`, `C = L_r^(1/2) V_r^T`; with more rows `R^T R = V L V^T`
/// (F x F), `Q = V_r`, `C = V_r^T R^T`; either way over the eigenvalues
/// above [`SPAN_TOLERANCE`] times the largest, so `C^T Q^T = R` up to the
/// dropped eigenvalues (rounding of rows that are exact combinations). The
/// eigendecomposition costs the cube of its size: of the K x K matrix it
/// took three minutes for a map of 4,798 rows of 16 dimensions (raw
/// per-pixel features), where the 16 x 16 one is immediate.
#[derive(Debug, Clone)]
struct Span {
    rank: usize,
    /// `Q`, column-major (F x r).
    basis: Vec<f32>,
    /// `C`, column-major (r x K).
    coords: Vec<f32>,
}

/// Eigenvalues of the Gram matrix below this fraction of the largest are
/// the rows' rounding, not their span: f32 rows of unit norm round at
/// about 1e-7 an element, so such eigenvalues are near 1e-12; a direction
/// the rows really take holds far more (the OMCL_GT plan's smallest kept
/// one is 2e-3 of the largest).
const SPAN_TOLERANCE: f64 = 1e-9;

impl Span {
    /// The span of `rows` (K x `dim`, row-major), if using it saves at
    /// least a fifth of the products.
    fn of(rows: &[f32], dim: usize) -> Option<Span> {
        use nalgebra::DMatrix;
        let k = rows.len() / dim;
        if k < 2 {
            return None;
        }
        let r = DMatrix::from_fn(k, dim, |i, j| rows[i * dim + j] as f64);
        let by_rows = k <= dim;
        let eig = match by_rows {
            true => (&r * r.transpose()).symmetric_eigen(),
            false => (r.transpose() * &r).symmetric_eigen(),
        };
        let top = eig.eigenvalues.max();
        let keep: Vec<usize> = (0..eig.eigenvalues.len())
            .filter(|&i| eig.eigenvalues[i] > SPAN_TOLERANCE * top)
            .collect();
        let rank = keep.len();
        if rank == 0 || 5 * rank * (dim + k) > 4 * dim * k {
            return None;
        }
        let mut basis = vec![0f32; dim * rank];
        let mut coords = vec![0f32; rank * k];
        for (c, &i) in keep.iter().enumerate() {
            let (l, v) = (eig.eigenvalues[i], eig.eigenvectors.column(i));
            // Basis vector q (F) and the rows' coordinates along it (K).
            let (q, along) = match by_rows {
                true => (r.transpose() * v / l.sqrt(), v * l.sqrt()),
                false => (v.into_owned(), &r * v),
            };
            for (b, x) in basis[c * dim..(c + 1) * dim].iter_mut().zip(q.iter()) {
                *b = *x as f32;
            }
            for (row, x) in along.iter().enumerate() {
                coords[row * rank + c] = *x as f32;
            }
        }
        Some(Span {
            rank,
            basis,
            coords,
        })
    }
}

impl FeatureDb {
    /// An empty database of `dim`-dimensional features with admission
    /// threshold `tau` (a cosine distance; the paper uses 0.02).
    pub fn new(dim: usize, tau: f32) -> Result<Self, FeatureDbError> {
        if dim == 0 {
            return Err(FeatureDbError::ZeroDim);
        }
        if !(0.0..=2.0).contains(&tau) {
            return Err(FeatureDbError::BadTau(tau));
        }
        Ok(FeatureDb {
            dim,
            tau,
            max_rows: None,
            rows: Vec::new(),
            span: std::sync::OnceLock::new(),
        })
    }

    /// Caps the number of rows; past it features map to their nearest row.
    pub fn with_max_rows(mut self, max_rows: usize) -> Self {
        self.max_rows = Some(max_rows.max(1));
        self
    }

    /// A database holding exactly `rows` (row-major, `dim` columns), each
    /// normalized, without the admission test: used for prompt features and
    /// for databases read from files. Rows already of unit norm (within
    /// 1e-6) are kept bit for bit, so files round-trip exactly.
    pub fn from_rows(dim: usize, tau: f32, mut rows: Vec<f32>) -> Result<Self, FeatureDbError> {
        let mut db = FeatureDb::new(dim, tau)?;
        if !rows.len().is_multiple_of(dim) {
            return Err(FeatureDbError::DimMismatch {
                expected: dim,
                got: rows.len() % dim,
            });
        }
        for (index, r) in rows.chunks_exact_mut(dim).enumerate() {
            let n2 = dot(r, r);
            if (n2 - 1.0).abs() <= 2e-6 {
                continue;
            }
            if !normalize(r) {
                return Err(FeatureDbError::Degenerate { index });
            }
        }
        db.rows = rows;
        Ok(db)
    }

    /// Feature dimension F.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Admission threshold (cosine distance).
    pub fn tau(&self) -> f32 {
        self.tau
    }

    /// Number of rows K.
    pub fn len(&self) -> usize {
        self.rows.len() / self.dim
    }

    /// Whether the database has no rows.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    /// Row `i` (unit norm).
    pub fn row(&self, i: usize) -> &[f32] {
        &self.rows[i * self.dim..(i + 1) * self.dim]
    }

    /// All rows, row-major.
    pub fn rows(&self) -> &[f32] {
        &self.rows
    }

    fn check(&self, f: &[f32]) -> Result<(), FeatureDbError> {
        if f.len() != self.dim {
            return Err(FeatureDbError::DimMismatch {
                expected: self.dim,
                got: f.len(),
            });
        }
        Ok(())
    }

    /// The most similar row to `f` (any norm) and its cosine similarity;
    /// `None` for an empty database or a feature without direction.
    pub fn nearest(&self, f: &[f32]) -> Result<Option<(usize, f32)>, FeatureDbError> {
        self.check(f)?;
        let n = dot(f, f).sqrt();
        if !(n.is_finite() && n > 0.0) || self.is_empty() {
            return Ok(None);
        }
        Ok(self.nearest_unit(f, n))
    }

    fn nearest_unit(&self, f: &[f32], norm: f32) -> Option<(usize, f32)> {
        let mut best = None::<(usize, f32)>;
        for (i, r) in self.rows.chunks_exact(self.dim).enumerate() {
            let s = dot(f, r) / norm;
            if best.is_none_or(|(_, b)| s > b) {
                best = Some((i, s));
            }
        }
        best
    }

    /// Dot products of `n` features with every row, fed to `f`: feature `j`
    /// is written by `fill(j, buf)` into a zeroed buffer of the database's
    /// dimension, and `f(feature, dots)` (dots: its K products with the rows,
    /// in row order, free to modify) gives the `j`-th output. Features go in
    /// blocks of 64, each block one matrix product (`products`, faer's
    /// kernels; nalgebra's GEMM before 2026-11-27, which was 2 times faster
    /// than one dot product at a time with 29 rows, 5 times with 200),
    /// blocks in parallel with buffers reused per thread.
    pub fn map_dots<T: Send>(
        &self,
        n: usize,
        fill: impl Fn(usize, &mut [f32]) + Sync,
        f: impl Fn(&[f32], &mut [f32]) -> T + Sync,
    ) -> Vec<T> {
        use rayon::prelude::*;
        const BLOCK: usize = 64;
        let (dim, k) = (self.dim, self.len());
        let blocks: Vec<Vec<T>> = (0..n.div_ceil(BLOCK))
            .into_par_iter()
            .map_init(
                || (vec![0f32; BLOCK * dim], vec![0f32; BLOCK * k]),
                |(fb, db), b| {
                    let (j0, j1) = (b * BLOCK, ((b + 1) * BLOCK).min(n));
                    let m = j1 - j0;
                    let (fb, db) = (&mut fb[..m * dim], &mut db[..m * k]);
                    fb.fill(0.0);
                    for (j, buf) in (j0..j1).zip(fb.chunks_exact_mut(dim)) {
                        fill(j, buf);
                    }
                    if k == 0 {
                        return fb.chunks_exact(dim).map(|feat| f(feat, &mut [])).collect();
                    }
                    products(db, fb, &self.rows, m, dim, k);
                    fb.chunks_exact(dim)
                        .zip(db.chunks_exact_mut(k))
                        .map(|(feat, dots)| f(feat, dots))
                        .collect()
                },
            )
            .collect();
        blocks.into_iter().flatten().collect()
    }

    /// Dot products of `n` features with every row and the features'
    /// norms, for callers that keep all of them (the sampler's clustering
    /// grid, whose products the similarity table reuses): `dots[j * K +
    /// k]` is feature `j` against row `k`, `norms[j]` its length. The
    /// features are read from `source`: a contiguous `n x F` slice is
    /// multiplied where it lies (no copy); otherwise they are written by a
    /// fill function into per-thread blocks, as [`FeatureDb::map_dots`]
    /// does.
    pub fn dots_and_norms(&self, n: usize, source: Features<'_>) -> (Vec<f32>, Vec<f32>) {
        use rayon::prelude::*;
        let (dim, k) = (self.dim, self.len());
        // Larger blocks than `map_dots`'s: the products are kept, and a
        // block of 128 features is 256 KiB of 512-d features (L2-sized).
        const BLOCK: usize = 128;
        let mut dots = vec![0f32; n * k];
        let mut norms = vec![0f32; n];
        if let Features::Slice(s) = source {
            assert_eq!(s.len(), n * dim, "feature slice of the wrong length");
        }
        // Through the rows' span where it is narrower (see `Span`).
        let span = if k > 0 { self.span() } else { None };
        let rank = span.map_or(0, |s| s.rank);
        dots.par_chunks_mut((BLOCK * k).max(1))
            .zip(norms.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each_init(
                || (vec![0f32; BLOCK * dim], vec![0f32; BLOCK * rank]),
                |(buf, proj), (b, (out, norms))| {
                    let (j0, m) = (b * BLOCK, norms.len());
                    let feats: &[f32] = match source {
                        Features::Slice(s) => &s[j0 * dim..(j0 + m) * dim],
                        Features::Fill(fill) => {
                            let buf = &mut buf[..m * dim];
                            buf.fill(0.0);
                            for (j, f) in (j0..j0 + m).zip(buf.chunks_exact_mut(dim)) {
                                fill(j, f);
                            }
                            buf
                        }
                    };
                    for (nj, f) in norms.iter_mut().zip(feats.chunks_exact(dim)) {
                        *nj = dot(f, f).sqrt();
                    }
                    match span {
                        Some(s) => {
                            // Q^T f, then C^T (Q^T f).
                            let proj = &mut proj[..m * s.rank];
                            products(proj, feats, &s.basis, m, dim, s.rank);
                            products(out, proj, &s.coords, m, s.rank, k);
                        }
                        None if k > 0 => products(out, feats, &self.rows, m, dim, k),
                        None => {}
                    }
                },
            );
        (dots, norms)
    }

    /// Cosine similarity of `f` to every row.
    pub fn similarities(&self, f: &[f32]) -> Result<Vec<f32>, FeatureDbError> {
        self.check(f)?;
        let n = dot(f, f).sqrt();
        let n = if n > 0.0 && n.is_finite() { n } else { 1.0 };
        Ok(self
            .rows
            .chunks_exact(self.dim)
            .map(|r| dot(f, r) / n)
            .collect())
    }

    /// Admits `f` if it is farther than `tau` (cosine distance) from every
    /// row and the cap allows, and returns the row that represents it: the
    /// new row, or the nearest existing one.
    pub fn admit(&mut self, f: &[f32]) -> Result<usize, FeatureDbError> {
        self.check(f)?;
        let n = dot(f, f).sqrt();
        if !(n.is_finite() && n > 0.0) {
            return Err(FeatureDbError::Degenerate { index: self.len() });
        }
        if let Some((i, s)) = self.nearest_unit(f, n) {
            let full = self.max_rows.is_some_and(|m| self.len() >= m);
            if 1.0 - s <= self.tau || full {
                return Ok(i);
            }
        }
        self.rows.extend(f.iter().map(|x| x / n));
        self.span = std::sync::OnceLock::new();
        Ok(self.len() - 1)
    }

    /// The rank of the rows' span when [`FeatureDb::dots_and_norms`] goes
    /// through it (see `Span`), else `None`.
    pub fn span_rank(&self) -> Option<usize> {
        self.span().map(|s| s.rank)
    }

    fn span(&self) -> Option<&Span> {
        self.span
            .get_or_init(|| Span::of(&self.rows, self.dim))
            .as_ref()
    }

    /// Bytes held by the rows.
    pub fn memory_bytes(&self) -> usize {
        self.rows.len() * std::mem::size_of::<f32>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DIM: usize = 37;

    /// Deterministic values in [-1, 1) for the products' tests.
    fn val(i: usize) -> f32 {
        ((i * 7919 % 1000) as f32 / 500.0) - 1.0
    }

    /// 23 rows of [`DIM`] values, not unit.
    fn test_db() -> FeatureDb {
        let rows: Vec<f32> = (0..23 * DIM).map(|i| val(i + 5)).collect();
        FeatureDb::from_rows(DIM, 0.0, rows).unwrap()
    }

    /// `dots_and_norms` gives every feature's products with the rows and
    /// its norm, the same from a slice as from a fill function, for counts
    /// that do and do not fill a block of 128.
    #[test]
    fn dots_and_norms_equal_single_dots() {
        let (dim, db) = (DIM, test_db());
        for n in [0, 1, 127, 128, 300] {
            let all: Vec<f32> = (0..n * dim).map(|i| val(3 * i + 1)).collect();
            let fill =
                |j: usize, buf: &mut [f32]| buf.copy_from_slice(&all[j * dim..(j + 1) * dim]);
            let (d1, n1) = db.dots_and_norms(n, Features::Slice(&all));
            let (d2, n2) = db.dots_and_norms(n, Features::Fill(&fill));
            assert_eq!((d1.len(), n1.len()), (n * db.len(), n));
            assert_eq!((&d1, &n1), (&d2, &n2));
            for j in 0..n {
                let f = &all[j * dim..(j + 1) * dim];
                assert!((n1[j] - dot(f, f).sqrt()).abs() <= 1e-5 * (1.0 + n1[j]));
                for k in 0..db.len() {
                    let (got, want) = (d1[j * db.len() + k], dot(f, db.row(k)));
                    assert!((got - want).abs() <= 1e-4 * (1.0 + want.abs()), "{j} {k}");
                }
            }
        }
    }

    /// Rows that are combinations of four directions (a floor plan's
    /// averages of its map's rows, in small) go through their span of rank
    /// 4, and their products equal the direct ones to rounding; 23 random
    /// rows in 37 dimensions (rank 23: no saving) do not. A row `admit`
    /// adds in a fifth direction widens the span.
    #[test]
    fn dependent_rows_go_through_their_span_with_the_same_products() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
        let mut draw =
            |n: usize| -> Vec<f32> { (0..n).map(|_| rng.random_range(-1.0..1.0)).collect() };
        let base: Vec<Vec<f32>> = (0..4).map(|_| draw(DIM)).collect();
        let weights: Vec<Vec<f32>> = (0..40).map(|_| draw(4)).collect();
        let rows: Vec<f32> = (0..40)
            .flat_map(|k| {
                let w = &weights[k];
                (0..DIM)
                    .map(|i| (0..4).map(|b| w[b] * base[b][i]).sum::<f32>())
                    .collect::<Vec<_>>()
            })
            .collect();
        let db = FeatureDb::from_rows(DIM, 0.0, rows).unwrap();
        assert_eq!(db.span_rank(), Some(4));
        let general = FeatureDb::from_rows(DIM, 0.0, draw(23 * DIM)).unwrap();
        assert_eq!(general.span_rank(), None);
        let n = 300;
        let all: Vec<f32> = (0..n * DIM).map(|i| val(3 * i + 1)).collect();
        let (d, norms) = db.dots_and_norms(n, Features::Slice(&all));
        for j in 0..n {
            let f = &all[j * DIM..(j + 1) * DIM];
            assert!((norms[j] - dot(f, f).sqrt()).abs() <= 1e-5 * (1.0 + norms[j]));
            for k in 0..db.len() {
                let (got, want) = (d[j * db.len() + k], dot(f, db.row(k)));
                assert!(
                    (got - want).abs() <= 1e-4 * (1.0 + want.abs()),
                    "{j} {k}: {got} {want}"
                );
            }
        }
        // Many rows in few dimensions (through the F x F Gram matrix):
        // 3,000 rows of rank 2 in 8 dimensions.
        let (b0, b1) = ([1.0f32, 0.5, 0.0, -1.0, 0.2, 0.0, 0.3, 0.1], [0.0f32; 8]);
        let b1 = {
            let mut b = b1;
            b[1] = 1.0;
            b[5] = -0.7;
            b
        };
        let many: Vec<f32> = (0..3000)
            .flat_map(|i| {
                let (x, y) = (val(i), val(i + 7));
                (0..8).map(move |j| x * b0[j] + y * b1[j])
            })
            .collect();
        let wide = FeatureDb::from_rows(8, 0.0, many).unwrap();
        assert_eq!(wide.span_rank(), Some(2));
        let f: Vec<f32> = (0..8).map(|i| val(5 * i + 2)).collect();
        let (d, _) = wide.dots_and_norms(1, Features::Slice(&f));
        for k in [0, 1, 1234, 2999] {
            let want = dot(&f, wide.row(k));
            assert!((d[k] - want).abs() <= 1e-4 * (1.0 + want.abs()), "{k}");
        }
        // A new direction resets the span: rank 5 of 41 rows still pays.
        let mut grown = db.clone();
        let new = draw(DIM);
        assert_eq!(grown.admit(&new).unwrap(), 40);
        assert_eq!(grown.span_rank(), Some(5));
        assert_eq!(grown, grown.clone());
        assert_ne!(grown, db);
    }

    /// The blocked products equal one dot product at a time (to
    /// rounding), for counts that do and do not fill a block, and each
    /// output sees its own feature.
    #[test]
    fn map_dots_equals_single_dots() {
        let (dim, db) = (DIM, test_db());
        for n in [0, 1, 7, 64, 300] {
            let feat = |j: usize, buf: &mut [f32]| {
                for (i, x) in buf.iter_mut().enumerate() {
                    *x = val(3 * (j * dim + i) + 1);
                }
            };
            let out = db.map_dots(n, feat, |f, d| (f.to_vec(), d.to_vec()));
            assert_eq!(out.len(), n);
            for (j, (f, d)) in out.iter().enumerate() {
                let mut want_f = vec![0.0; dim];
                feat(j, &mut want_f);
                assert_eq!(f, &want_f);
                assert_eq!(d.len(), db.len());
                for (k, &got) in d.iter().enumerate() {
                    let want = dot(&want_f, db.row(k));
                    assert!(
                        (got - want).abs() <= 1e-4 * (1.0 + want.abs()),
                        "{j} {k}: {got} vs {want}"
                    );
                }
            }
        }
        // An empty database gives empty products.
        let empty = FeatureDb::new(dim, 0.0).unwrap();
        let out = empty.map_dots(3, |_, _| {}, |_, d| d.len());
        assert_eq!(out, [0, 0, 0]);
    }

    fn unit(angle_deg: f32) -> Vec<f32> {
        let a = angle_deg.to_radians();
        vec![a.cos(), a.sin(), 0.0]
    }

    #[test]
    fn admission_obeys_tau() {
        // tau = 0.02 is a cosine distance: angle acos(0.98) = 11.48 degrees.
        let mut db = FeatureDb::new(3, 0.02).unwrap();
        assert_eq!(db.admit(&unit(0.0)).unwrap(), 0);
        // 10 degrees: distance 1 - cos(10) = 0.0152 <= tau: not admitted.
        assert_eq!(db.admit(&unit(10.0)).unwrap(), 0);
        assert_eq!(db.len(), 1);
        // 13 degrees: distance 0.0256 > tau: a new row.
        assert_eq!(db.admit(&unit(13.0)).unwrap(), 1);
        // 20 degrees is nearer row 1 (7 degrees away) than row 0.
        assert_eq!(db.admit(&unit(20.0)).unwrap(), 1);
        assert_eq!(db.len(), 2);
        // Every pair of rows is farther apart than tau.
        assert!(1.0 - dot(db.row(0), db.row(1)) > 0.02);
    }

    #[test]
    fn rows_are_unit_norm_whatever_the_input_scale() {
        let mut db = FeatureDb::new(3, 0.1).unwrap();
        db.admit(&[0.0, 5.0, 0.0]).unwrap();
        assert_eq!(db.row(0), &[0.0, 1.0, 0.0]);
        let (i, s) = db.nearest(&[0.0, 0.1, 0.0]).unwrap().unwrap();
        assert_eq!(i, 0);
        assert!((s - 1.0).abs() < 1e-6);
    }

    #[test]
    fn cap_maps_to_nearest() {
        let mut db = FeatureDb::new(3, 0.0).unwrap().with_max_rows(2);
        db.admit(&[1.0, 0.0, 0.0]).unwrap();
        db.admit(&[0.0, 1.0, 0.0]).unwrap();
        assert_eq!(db.admit(&[0.1, 0.9, 0.3]).unwrap(), 1);
        assert_eq!(db.len(), 2);
    }

    #[test]
    fn bad_input_is_rejected() {
        let mut db = FeatureDb::new(3, 0.02).unwrap();
        assert!(matches!(
            db.admit(&[1.0, 0.0]),
            Err(FeatureDbError::DimMismatch {
                expected: 3,
                got: 2
            })
        ));
        assert!(matches!(
            db.admit(&[0.0, 0.0, 0.0]),
            Err(FeatureDbError::Degenerate { .. })
        ));
        assert!(db.admit(&[f32::NAN, 1.0, 0.0]).is_err());
        assert!(FeatureDb::new(0, 0.1).is_err());
        assert!(FeatureDb::new(3, -0.1).is_err());
        assert!(FeatureDb::from_rows(2, 0.1, vec![1.0, 0.0, 0.0, 0.0]).is_err());
    }

    #[test]
    fn dot_handles_tails() {
        let a: Vec<f32> = (0..19).map(|i| i as f32).collect();
        let expected: f32 = a.iter().map(|x| x * x).sum();
        assert_eq!(dot(&a, &a), expected);
    }
}
