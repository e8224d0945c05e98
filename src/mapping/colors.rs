//! Colours for looking at maps: a palette for feature rows and a heat map
//! for similarities (the paper's Figure 1).

/// A distinct colour for row `r` (golden-ratio hue steps).
pub fn row_color(r: u32) -> [u8; 3] {
    let h = (r as f64 * 0.618_033_988_749_895).fract();
    hsv(h, 0.65, 0.95)
}

/// The "turbo"-like heat colour of `t` in [0, 1] (blue, cyan, green,
/// yellow, red); values outside are clamped.
pub fn heat_color(t: f32) -> [u8; 3] {
    let t = t.clamp(0.0, 1.0) as f64;
    // Hue from 240 degrees (blue) down to 0 (red).
    hsv((1.0 - t) * 2.0 / 3.0, 0.9, 0.35 + 0.65 * t.max(0.25))
}

fn hsv(h: f64, s: f64, v: f64) -> [u8; 3] {
    let i = (h * 6.0).floor();
    let f = h * 6.0 - i;
    let (p, q, t) = (v * (1.0 - s), v * (1.0 - f * s), v * (1.0 - (1.0 - f) * s));
    let (r, g, b) = match i as i64 % 6 {
        0 => (v, t, p),
        1 => (q, v, p),
        2 => (p, v, t),
        3 => (p, q, v),
        4 => (t, p, v),
        _ => (v, p, q),
    };
    [(r * 255.0) as u8, (g * 255.0) as u8, (b * 255.0) as u8]
}

/// Rescales similarities to [0, 1] between their minimum and maximum (so
/// the hottest voxels are the best matches whatever the encoder's range).
pub fn normalize_range(s: &[f32]) -> Vec<f32> {
    let lo = s.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = s.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let span = if hi > lo { hi - lo } else { 1.0 };
    s.iter().map(|x| (x - lo) / span).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heat_runs_from_blue_to_red() {
        let cold = heat_color(0.0);
        let hot = heat_color(1.0);
        assert!(cold[2] > cold[0], "{cold:?}");
        assert!(hot[0] > 200 && hot[2] < 50, "{hot:?}");
        assert_eq!(normalize_range(&[1.0, 3.0, 2.0]), vec![0.0, 1.0, 0.5]);
    }

    #[test]
    fn neighbouring_rows_get_different_colours() {
        for r in 0..50 {
            assert_ne!(row_color(r), row_color(r + 1));
        }
    }
}
