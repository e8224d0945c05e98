//! Colour classes: a small, fixed, NOT open-vocabulary image encoder for
//! real images when no language model is at hand.
//!
//! Each pixel's sRGB colour goes to CIE L\*a\*b\* (D65, the standard sRGB
//! transfer curve and matrix), is assigned to the nearest of K centroids
//! fitted by k-means on mapping images, and is described by that class's
//! unit embedding. [`ColourClasses::classify`] is the reference the
//! exported ONNX graph ([`super::colour_model`]) is checked against; both
//! compute the same steps in the same order, in `f32`.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// sRGB's linear-to-XYZ matrix (IEC 61966-2-1), rows X, Y, Z.
pub const SRGB_TO_XYZ: [[f32; 3]; 3] = [
    [0.412_456_4, 0.357_576_1, 0.180_437_5],
    [0.212_672_9, 0.715_152_2, 0.072_175],
    [0.019_333_9, 0.119_192, 0.950_304_1],
];

/// The D65 white point (X, Y, Z) with Y = 1.
pub const D65_WHITE: [f32; 3] = [0.950_47, 1.0, 1.088_83];

/// The linear-to-XYZ matrix with each row divided by the white point's
/// component: `xyz / white` in one product.
pub fn xyz_over_white() -> [[f32; 3]; 3] {
    let mut m = SRGB_TO_XYZ;
    for (row, w) in m.iter_mut().zip(D65_WHITE) {
        row.iter_mut().for_each(|v| *v /= w);
    }
    m
}

/// sRGB's transfer curve undone: `c` in [0, 1] to linear light.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.040_45 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// CIE Lab's `f(t)`: the cube root above `(6/29)^3`, its tangent line below.
pub fn lab_f(t: f32) -> f32 {
    const D: f32 = 6.0 / 29.0;
    if t > D * D * D {
        t.powf(1.0 / 3.0)
    } else {
        t / (3.0 * D * D) + 4.0 / 29.0
    }
}

/// CIE L\*a\*b\* (D65) of an 8-bit sRGB colour: L in [0, 100].
pub fn srgb8_to_lab(rgb: [u8; 3]) -> [f32; 3] {
    let lin = rgb.map(|c| srgb_to_linear(c as f32 / 255.0));
    let m = xyz_over_white();
    let f = m.map(|row| lab_f(row[0] * lin[0] + row[1] * lin[1] + row[2] * lin[2]));
    [
        116.0 * f[1] - 16.0,
        500.0 * (f[0] - f[1]),
        200.0 * (f[1] - f[2]),
    ]
}

/// Errors of fitting colour classes.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ColourError {
    #[error("k-means needs at least {k} colours for k = {k}, got {n}")]
    TooFewColours { n: usize, k: usize },
    #[error("the number of colour classes must be 1 to {max}, got {k}")]
    BadK { k: usize, max: usize },
    #[error("the embedding dimension must be 2 to {max}, got {dim}")]
    BadDim { dim: usize, max: usize },
}

/// Most colour classes: embeddings and scores stay small.
pub const MAX_CLASSES: usize = 256;

/// Longest class embedding (CLIP's is 512, LSeg's 512; `--dim 10000000000`
/// asked for 400 GB and aborted).
pub const MAX_DIM: usize = 4096;

/// K colour classes: Lab centroids and one unit embedding each.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ColourClasses {
    /// Lab centroid of each class.
    pub centroids: Vec<[f32; 3]>,
    /// Embedding length F.
    pub dim: usize,
    /// `K x F` unit rows, row-major.
    pub embeddings: Vec<f32>,
}

impl ColourClasses {
    /// Fits `k` centroids to `lab` colours by k-means (k-means++ seeding,
    /// at most `iterations` Lloyd steps, all draws from `seed`) and gives
    /// each class a unit embedding of length `dim`: an independent standard
    /// Gaussian draw from the same seed, normalised (in 32 or more
    /// dimensions two such rows have a cosine near 0, about +-0.18).
    pub fn fit(
        lab: &[[f32; 3]],
        k: usize,
        dim: usize,
        iterations: usize,
        seed: u64,
    ) -> Result<ColourClasses, ColourError> {
        if k == 0 || k > MAX_CLASSES {
            return Err(ColourError::BadK {
                k,
                max: MAX_CLASSES,
            });
        }
        if !(2..=MAX_DIM).contains(&dim) {
            return Err(ColourError::BadDim { dim, max: MAX_DIM });
        }
        if lab.len() < k {
            return Err(ColourError::TooFewColours { n: lab.len(), k });
        }
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut centroids = kmeans_pp(lab, k, &mut rng);
        let mut assign = vec![0usize; lab.len()];
        for _ in 0..iterations {
            let mut changed = false;
            for (a, p) in assign.iter_mut().zip(lab) {
                let c = nearest(&centroids, p);
                changed |= c != *a;
                *a = c;
            }
            let mut sum = vec![[0f64; 3]; k];
            let mut count = vec![0usize; k];
            for (&a, p) in assign.iter().zip(lab) {
                count[a] += 1;
                (0..3).for_each(|j| sum[a][j] += p[j] as f64);
            }
            for c in 0..k {
                // An emptied class keeps its centroid.
                if count[c] > 0 {
                    centroids[c] = sum[c].map(|s| (s / count[c] as f64) as f32);
                }
            }
            if !changed {
                break;
            }
        }
        // Classes ordered by lightness, so class ids read dark to light.
        centroids.sort_by(|a, b| a[0].total_cmp(&b[0]));
        let mut embeddings = Vec::with_capacity(k * dim);
        for _ in 0..k {
            let row: Vec<f32> = (0..dim)
                .map(|_| StandardNormal.sample(&mut rng))
                .collect::<Vec<f64>>()
                .into_iter()
                .map(|v| v as f32)
                .collect();
            let n = row.iter().map(|v| v * v).sum::<f32>().sqrt().max(1e-12);
            embeddings.extend(row.iter().map(|v| v / n));
        }
        Ok(ColourClasses {
            centroids,
            dim,
            embeddings,
        })
    }

    /// Number of classes K.
    pub fn len(&self) -> usize {
        self.centroids.len()
    }

    /// Whether there are no classes (never for a fitted set).
    pub fn is_empty(&self) -> bool {
        self.centroids.is_empty()
    }

    /// The class of a Lab colour: the centroid `c` maximising
    /// `2 lab . c - |c|^2` (the nearest; ties to the lowest index), the
    /// score the ONNX graph computes.
    pub fn classify_lab(&self, lab: &[f32; 3]) -> usize {
        nearest(&self.centroids, lab)
    }

    /// The class of an 8-bit sRGB colour.
    pub fn classify(&self, rgb: [u8; 3]) -> usize {
        self.classify_lab(&srgb8_to_lab(rgb))
    }

    /// The unit embedding of class `c`.
    pub fn embedding(&self, c: usize) -> &[f32] {
        &self.embeddings[c * self.dim..(c + 1) * self.dim]
    }
}

/// Index of the centroid nearest to `p` by `2 p . c - |c|^2` (largest
/// wins, first on ties).
fn nearest(centroids: &[[f32; 3]], p: &[f32; 3]) -> usize {
    let mut best = (0, f32::NEG_INFINITY);
    for (i, c) in centroids.iter().enumerate() {
        let s = 2.0 * (p[0] * c[0] + p[1] * c[1] + p[2] * c[2])
            - (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        if s > best.1 {
            best = (i, s);
        }
    }
    best.0
}

fn dist2(a: &[f32; 3], b: &[f32; 3]) -> f32 {
    (0..3).map(|j| (a[j] - b[j]) * (a[j] - b[j])).sum()
}

/// k-means++ seeding: the first centre uniform, each next one drawn with
/// probability proportional to the squared distance to the nearest centre.
fn kmeans_pp(lab: &[[f32; 3]], k: usize, rng: &mut ChaCha8Rng) -> Vec<[f32; 3]> {
    let mut centres = vec![lab[rng.random_range(0..lab.len())]];
    let mut d2: Vec<f64> = lab.iter().map(|p| dist2(p, &centres[0]) as f64).collect();
    while centres.len() < k {
        let total: f64 = d2.iter().sum();
        let next = if total > 0.0 {
            let mut r = rng.random::<f64>() * total;
            let mut pick = lab.len() - 1;
            for (i, d) in d2.iter().enumerate() {
                if r < *d {
                    pick = i;
                    break;
                }
                r -= d;
            }
            pick
        } else {
            // All colours coincide with a centre: any colour will do.
            rng.random_range(0..lab.len())
        };
        let c = lab[next];
        centres.push(c);
        d2.iter_mut()
            .zip(lab)
            .for_each(|(d, p)| *d = d.min(dist2(p, &c) as f64));
    }
    centres
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_of_known_colours() {
        // Reference values (D65): white (100, 0, 0), black (0, 0, 0),
        // sRGB red (53.24, 80.09, 67.20), mid grey 128 L = 53.59.
        let close = |a: [f32; 3], b: [f32; 3], tol: f32| (0..3).all(|i| (a[i] - b[i]).abs() < tol);
        assert!(close(
            srgb8_to_lab([255, 255, 255]),
            [100.0, 0.0, 0.0],
            0.01
        ));
        assert!(close(srgb8_to_lab([0, 0, 0]), [0.0, 0.0, 0.0], 1e-4));
        assert!(close(
            srgb8_to_lab([255, 0, 0]),
            [53.24, 80.09, 67.20],
            0.02
        ));
        assert!(close(
            srgb8_to_lab([128, 128, 128]),
            [53.59, 0.0, 0.0],
            0.01
        ));
    }

    #[test]
    fn kmeans_finds_three_clusters_and_classifies_them() {
        let mut lab = Vec::new();
        for i in 0..300 {
            let e = (i % 7) as f32 * 0.1;
            lab.push([20.0 + e, 0.0, 0.0]);
            lab.push([50.0, 40.0 + e, 0.0]);
            lab.push([80.0, 0.0, -30.0 + e]);
        }
        let c = ColourClasses::fit(&lab, 3, 16, 50, 3).unwrap();
        // Sorted by L: the dark cluster is class 0.
        assert!((c.centroids[0][0] - 20.3).abs() < 0.01, "{:?}", c.centroids);
        assert!((c.centroids[1][1] - 40.3).abs() < 0.01, "{:?}", c.centroids);
        assert!((c.centroids[2][2] + 29.7).abs() < 0.01, "{:?}", c.centroids);
        assert_eq!(c.classify_lab(&[25.0, 1.0, 1.0]), 0);
        assert_eq!(c.classify_lab(&[60.0, 30.0, 0.0]), 1);
        for k in 0..3 {
            let n: f32 = c.embedding(k).iter().map(|v| v * v).sum();
            assert!((n - 1.0).abs() < 1e-5);
        }
        assert_eq!(
            ColourClasses::fit(&lab[..2], 3, 16, 5, 0).unwrap_err(),
            ColourError::TooFewColours { n: 2, k: 3 }
        );
        assert!(ColourClasses::fit(&lab, 0, 16, 5, 0).is_err());
        // Same seed, same classes.
        assert_eq!(c, ColourClasses::fit(&lab, 3, 16, 50, 3).unwrap());
    }
}
