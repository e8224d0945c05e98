//! Figures written to PNG and SVG and read back: sizes, colours at known
//! places, texts, and the errors.

use std::path::Path;

use image::{Rgb, RgbImage};
use plotters::prelude::{ColorMap, ViridisRGB};

use super::output::{Figure, write_figure};
use super::style::error_colour;
use super::trajectory::{PanelLayout, TrajectoryFigure};
use super::*;

fn read_png(path: &Path) -> RgbImage {
    image::open(path).unwrap().to_rgb8()
}

fn colours(img: &RgbImage) -> std::collections::HashSet<[u8; 3]> {
    img.pixels().map(|p| p.0).collect()
}

fn count(img: &RgbImage, c: [u8; 3]) -> usize {
    img.pixels().filter(|p| p.0 == c).count()
}

/// The texts of an SVG's `<text>` elements (plotters puts each on its own
/// line between the tags).
fn svg_texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|t| {
            let body = &t[t.find('>')? + 1..t.find("</text>")?];
            Some(body.trim().to_string())
        })
        .collect()
}

fn rgb(c: plotters::style::RGBColor) -> [u8; 3] {
    [c.0, c.1, c.2]
}

fn ablation_axes() -> Axes {
    Axes {
        title: "Number of particles".into(),
        x_label: "particles".into(),
        y_label: "APE RMSE [m]".into(),
        log_x: true,
        log_y: false,
    }
}

fn ablation_series() -> Vec<Series> {
    [256.0, 1024.0]
        .iter()
        .enumerate()
        .map(|(k, rays)| Series {
            label: format!("{rays} rays"),
            points: (6..=14)
                .map(|e| {
                    let n = 2f64.powi(e);
                    (n, 0.1 + 0.8 / (e as f64 - 5.0) + 0.02 * k as f64)
                })
                .collect(),
        })
        .collect()
}

#[test]
fn line_plot_writes_png_and_svg() {
    let dir = tempfile::tempdir().unwrap();
    let (axes, series) = (ablation_axes(), ablation_series());
    let png_path = dir.path().join("particles.png");
    line_plot(&png_path, &axes, &series).unwrap();
    let img = read_png(&png_path);
    assert_eq!(img.dimensions(), (800, 560));
    let seen = colours(&img);
    assert!(seen.len() > 2, "a plot, not a blank canvas");
    // Both series' colours are on the canvas.
    for i in 0..2 {
        let c = rgb(style::series_colour(i));
        assert!(count(&img, c) > 100, "series {i} colour {c:?} drawn");
    }
    // Text is rasterised from the embedded font: dark grey-level glyph
    // pixels (anti-aliased, so not only pure black) exist.
    assert!(
        img.pixels()
            .any(|p| p.0[0] == p.0[1] && p.0[1] == p.0[2] && p.0[0] > 30 && p.0[0] < 200)
    );

    let svg_path = dir.path().join("particles.SVG");
    line_plot(&svg_path, &axes, &series).unwrap();
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    let texts = svg_texts(&svg);
    for text in [
        "Number of particles",
        "particles",
        "APE RMSE [m]",
        "256 rays",
        "1024 rays",
    ] {
        assert!(texts.iter().any(|t| t == text), "SVG has {text:?}");
    }
    // Few distinct x values: ticks exactly at the sweep's values.
    for e in 6..=14 {
        let tick = (1u32 << e).to_string();
        assert!(texts.contains(&tick), "SVG has the tick {tick}: {texts:?}");
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&png_path).unwrap().permissions().mode();
        assert_eq!(mode & 0o777, 0o644, "figures are readable by others");
    }
    // Nothing else left in the directory (the temp files were renamed).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn line_plot_skips_non_finite_and_non_positive_on_log_axes() {
    let dir = tempfile::tempdir().unwrap();
    let mut axes = ablation_axes();
    axes.log_y = true;
    let series = vec![
        Series {
            label: "with gaps".into(),
            points: vec![
                (1.0, 1.0),
                (f64::NAN, 2.0),
                (2.0, f64::INFINITY),
                (0.0, 1.0),  // x = 0 is not on a log axis
                (3.0, -1.0), // nor is y = -1
                (4.0, 0.5),
            ],
        },
        Series {
            label: "nothing drawable".into(),
            points: vec![(f64::NAN, f64::NAN)],
        },
    ];
    for ext in ["png", "svg"] {
        line_plot(&dir.path().join(format!("gaps.{ext}")), &axes, &series).unwrap();
    }
    let img = read_png(&dir.path().join("gaps.png"));
    assert!(count(&img, rgb(style::series_colour(0))) > 20);
}

#[test]
fn bar_plot_heights_and_texts() {
    let dir = tempfile::tempdir().unwrap();
    let axes = Axes {
        title: "Sampling strategies".into(),
        x_label: "rays".into(),
        y_label: "APE RMSE [m]".into(),
        log_x: false,
        log_y: false,
    };
    // Series "uniform" is three times as tall as "stratified" in each group.
    let groups: Vec<BarGroup> = ["256", "1024"]
        .iter()
        .map(|label| BarGroup {
            label: label.to_string(),
            bars: vec![
                ("stratified".into(), 0.1, Some(0.02)),
                ("uniform".into(), 0.3, None),
                ("equal".into(), f64::NAN, Some(f64::NAN)),
            ],
        })
        .collect();
    let png_path = dir.path().join("strategies.png");
    bar_plot(&png_path, &axes, &groups).unwrap();
    let img = read_png(&png_path);
    assert_eq!(img.dimensions().1, 560);
    let (a, b) = (
        count(&img, rgb(style::series_colour(0))),
        count(&img, rgb(style::series_colour(1))),
    );
    // Equal widths, heights 0.1 and 0.3 from a zero baseline: 3x the area
    // (less the legend squares, 15 x 15 pixels each).
    let ratio = (b - 225) as f64 / (a - 225) as f64;
    assert!(
        (ratio - 3.0).abs() < 0.15,
        "area ratio {ratio} ({a} vs {b} pixels)"
    );
    // The NaN series is listed (legend) but has no bar.
    assert!(count(&img, rgb(style::series_colour(2))) <= 225);

    let svg_path = dir.path().join("strategies.svg");
    bar_plot(&svg_path, &axes, &groups).unwrap();
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    let texts = svg_texts(&svg);
    for text in [
        "Sampling strategies",
        "rays",
        "APE RMSE [m]",
        "stratified",
        "uniform",
        "equal",
        "256",
        "1024",
    ] {
        assert!(
            texts.iter().any(|t| t == text),
            "SVG has {text:?}: {texts:?}"
        );
    }
}

#[test]
fn bar_plot_log_y_and_negative_values() {
    let dir = tempfile::tempdir().unwrap();
    let mut axes = Axes {
        title: "fps".into(),
        log_y: true,
        ..Axes::default()
    };
    let groups = vec![BarGroup {
        label: "g".into(),
        bars: vec![
            ("a".into(), 10.0, Some(20.0)),
            ("b".into(), 1000.0, Some(1.0)),
        ],
    }];
    bar_plot(&dir.path().join("log.png"), &axes, &groups).unwrap();
    axes.log_y = false;
    let negative = vec![BarGroup {
        label: "g".into(),
        bars: vec![("a".into(), -1.0, Some(0.5)), ("b".into(), 2.0, None)],
    }];
    bar_plot(&dir.path().join("neg.svg"), &axes, &negative).unwrap();
}

/// A 10 m x 6 m room of 0.1 m cells, all floor except a wall block at
/// x in [4, 5), y in [0, 3).
fn room() -> FloorPlan {
    let (width, height) = (100, 60);
    let mut cells = vec![PlanCell::Floor; width * height];
    for row in 0..30 {
        for col in 40..50 {
            cells[row * width + col] = PlanCell::Obstacle;
        }
    }
    FloorPlan {
        min_xy: [0.0, 0.0],
        cell: 0.1,
        width,
        height,
        cells,
    }
}

/// Ground truth along y = 4.5 from x = 1 to 9, estimates beside it with
/// errors rising to the right; the largest error is at (9, 5) and the
/// smallest at (1, 4.5), both isolated.
fn paths() -> (Vec<[f64; 2]>, Vec<[f64; 2]>, Vec<f64>) {
    let gt: Vec<[f64; 2]> = (0..=80).map(|i| [1.0 + 0.1 * i as f64, 4.5]).collect();
    let mut est = Vec::new();
    let mut err = Vec::new();
    for i in 0..=8 {
        let x = 1.0 + i as f64;
        let offset = 0.0625 * i as f64;
        est.push([x, 4.5 + offset]);
        err.push(offset);
    }
    (gt, est, err)
}

/// Pixel of world (x, y) computed from the layout's window, independently
/// of plotters' mapping: x right, y up.
fn to_pixel(l: &PanelLayout, x: f64, y: f64) -> (i32, i32) {
    let fx = (x - l.x_range.0) / (l.x_range.1 - l.x_range.0);
    let fy = (y - l.y_range.0) / (l.y_range.1 - l.y_range.0);
    let px = l.pixels_x.0 as f64 + fx * (l.pixels_x.1 - l.pixels_x.0) as f64;
    let py = l.pixels_y.1 as f64 - fy * (l.pixels_y.1 - l.pixels_y.0) as f64;
    (px.round() as i32, py.round() as i32)
}

fn pixel(img: &RgbImage, (x, y): (i32, i32)) -> [u8; 3] {
    let Rgb(c) = *img.get_pixel(x as u32, y as u32);
    c
}

#[test]
fn trajectory_plot_colours_at_known_places() {
    let dir = tempfile::tempdir().unwrap();
    let plan = room();
    let (gt, est, err) = paths();
    let panel = TrajectoryPanel {
        title: "seq 00",
        plan: Some(&plan),
        gt_xy: &gt,
        est_xy: &est,
        errors_m: &err,
    };
    let path = dir.path().join("trajectory.png");
    let figure = TrajectoryFigure::new(&path, std::slice::from_ref(&panel)).unwrap();
    let layouts = write_figure(&path, &figure).unwrap();
    let l = &layouts[0];
    let img = read_png(&path);
    assert_eq!(img.dimensions(), figure.size());

    // Equal scale: as many pixels per metre along x as along y.
    let sx = (l.pixels_x.1 - l.pixels_x.0) as f64 / (l.x_range.1 - l.x_range.0);
    let sy = (l.pixels_y.1 - l.pixels_y.0) as f64 / (l.y_range.1 - l.y_range.0);
    assert!(
        (sx / sy - 1.0).abs() < 0.01,
        "{sx} vs {sy} pixels per metre"
    );
    // The whole room is in the window.
    assert!(l.x_range.0 <= 0.0 && l.x_range.1 >= 10.0 && l.y_range.0 <= 0.0 && l.y_range.1 >= 6.0);

    // The largest error (at x = 9, y = 5) is drawn in viridis' top colour,
    // where an independent mapping puts it (so x is right, y is up).
    let top = rgb(ViridisRGB.get_color(1.0));
    assert_eq!(top, [254, 232, 37]);
    let p_max = to_pixel(l, 9.0, 5.0);
    let drawn = l.est_pixels[8].unwrap();
    assert!((drawn.0 - p_max.0).abs() <= 1 && (drawn.1 - p_max.1).abs() <= 1);
    assert_eq!(pixel(&img, p_max), top);
    // The smallest (0 m at x = 1) in the bottom colour.
    assert_eq!(
        pixel(&img, to_pixel(l, 1.0, 4.5)),
        rgb(ViridisRGB.get_color(0.0))
    );
    // The middle estimate in the middle of the map.
    assert_eq!(
        pixel(&img, to_pixel(l, 5.0, 4.75)),
        rgb(error_colour(0.25, 0.5))
    );

    // Obstacle cells are dark; floor away from the paths is light grey;
    // outside the plan is white.
    for (x, y) in [(4.5, 1.5), (4.05, 0.2), (4.95, 2.8)] {
        let c = pixel(&img, to_pixel(l, x, y));
        assert!(
            c.iter().all(|v| *v < 100),
            "obstacle at ({x}, {y}) is {c:?}"
        );
    }
    for (x, y) in [(2.0, 2.0), (7.0, 1.5)] {
        assert_eq!(
            pixel(&img, to_pixel(l, x, y)),
            [222, 222, 222],
            "floor at ({x}, {y})"
        );
    }
    let outside = to_pixel(l, l.x_range.1 - 0.05, 3.0);
    assert_eq!(pixel(&img, outside), [255, 255, 255]);

    // The ground-truth line is black between estimates.
    let on_line = to_pixel(l, 1.5, 4.5);
    let dark = (-1..=1).any(|d| pixel(&img, (on_line.0, on_line.1 + d)) == [0, 0, 0]);
    assert!(dark, "ground truth drawn at {on_line:?}");

    // Colour bar: dark purple at the bottom, yellow at the top.
    let (x0, x1, yt, yb) = l.colour_bar;
    let near = |a: [u8; 3], b: [u8; 3]| {
        a.iter()
            .zip(b)
            .all(|(u, v)| (*u as i32 - v as i32).abs() <= 12)
    };
    assert!(near(pixel(&img, ((x0 + x1) / 2, yt + 2)), top));
    assert!(near(
        pixel(&img, ((x0 + x1) / 2, yb - 2)),
        rgb(ViridisRGB.get_color(0.0))
    ));

    let svg_path = dir.path().join("trajectory.svg");
    trajectory_plot(&svg_path, &panel).unwrap();
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    let texts = svg_texts(&svg);
    for text in [
        "seq 00",
        "x [m]",
        "y [m]",
        "APE [m]",
        "ground truth",
        "start",
    ] {
        assert!(texts.iter().any(|t| t == text), "SVG has {text:?}");
    }
    // The plan is drawn as row runs, not one rectangle per cell.
    assert!(svg.matches("<rect").count() < 1000);
}

#[test]
fn trajectory_plot_without_plan_and_with_non_finite_values() {
    let dir = tempfile::tempdir().unwrap();
    let gt = vec![[0.0, 0.0], [f64::NAN, 1.0], [1.0, 1.0], [2.0, 1.0]];
    let est = vec![[0.1, 0.0], [f64::INFINITY, 1.0], [1.0, 1.1], [2.0, 1.3]];
    let err = vec![0.1, 0.2, f64::NAN, 0.3];
    let panel = TrajectoryPanel {
        title: "",
        plan: None,
        gt_xy: &gt,
        est_xy: &est,
        errors_m: &err,
    };
    let path = dir.path().join("bare.png");
    let figure = TrajectoryFigure::new(&path, std::slice::from_ref(&panel)).unwrap();
    let layouts = write_figure(&path, &figure).unwrap();
    let drawn: Vec<bool> = layouts[0].est_pixels.iter().map(Option::is_some).collect();
    assert_eq!(drawn, vec![true, false, false, true]);
    let img = read_png(&path);
    assert_eq!(
        pixel(&img, layouts[0].est_pixels[3].unwrap()),
        [254, 232, 37]
    );
    // All errors zero: one colour, no division by zero.
    let zeros = vec![0.0; 4];
    let flat = TrajectoryPanel {
        errors_m: &zeros,
        ..panel
    };
    trajectory_plot(&dir.path().join("zeros.svg"), &flat).unwrap();
}

#[test]
fn trajectory_grid_draws_every_panel() {
    let dir = tempfile::tempdir().unwrap();
    let plan = room();
    let (gt, est, err) = paths();
    let titles = ["seq A", "seq B", "seq C"];
    let panels: Vec<TrajectoryPanel> = titles
        .iter()
        .map(|t| TrajectoryPanel {
            title: t,
            plan: Some(&plan),
            gt_xy: &gt,
            est_xy: &est,
            errors_m: &err,
        })
        .collect();
    let png_path = dir.path().join("grid.png");
    let figure = TrajectoryFigure::new(&png_path, &panels).unwrap();
    let layouts = write_figure(&png_path, &figure).unwrap();
    let img = read_png(&png_path);
    assert_eq!(img.dimensions(), (2 * 640, 2 * 560));
    // Panel 2 is in the second row, first column; its largest error is
    // yellow where it should be.
    let l = &layouts[2];
    assert!(l.pixels_x.1 < 640 && l.pixels_y.0 > 560);
    assert_eq!(pixel(&img, to_pixel(l, 9.0, 5.0)), [254, 232, 37]);
    let svg_path = dir.path().join("grid.svg");
    trajectory_grid(&svg_path, &panels).unwrap();
    let svg = std::fs::read_to_string(&svg_path).unwrap();
    let texts = svg_texts(&svg);
    for t in titles {
        assert!(texts.iter().any(|s| s == t), "SVG has {t:?}");
    }
}

#[test]
fn errors_name_the_problem_and_leave_files_alone() {
    let dir = tempfile::tempdir().unwrap();
    let axes = ablation_axes();
    let series = ablation_series();

    for name in ["plot.jpg", "plot", "plot.png.txt"] {
        let path = dir.path().join(name);
        let e = line_plot(&path, &axes, &series).unwrap_err();
        assert!(matches!(e, PlotError::UnknownFormat { .. }), "{name}: {e}");
        assert!(e.to_string().contains(name) && e.to_string().contains(".png or .svg"));
        assert!(!path.exists());
    }

    // Empty and all-non-finite data: an error, and an existing figure is
    // not touched.
    let keep = dir.path().join("keep.png");
    std::fs::write(&keep, b"old figure").unwrap();
    for bad in [
        vec![],
        vec![Series::default()],
        vec![Series {
            label: "nan".into(),
            points: vec![(f64::NAN, 1.0), (1.0, f64::NEG_INFINITY)],
        }],
    ] {
        let e = line_plot(&keep, &axes, &bad).unwrap_err();
        assert!(matches!(e, PlotError::Empty { .. }), "{e}");
        assert!(e.to_string().contains("keep.png"));
    }
    assert_eq!(std::fs::read(&keep).unwrap(), b"old figure");

    let e = bar_plot(&keep, &Axes::default(), &[]).unwrap_err();
    assert!(matches!(e, PlotError::Empty { .. }), "{e}");
    let log_x = Axes {
        log_x: true,
        ..Axes::default()
    };
    let group = BarGroup {
        label: "g".into(),
        bars: vec![("a".into(), 1.0, None)],
    };
    let e = bar_plot(&keep, &log_x, std::slice::from_ref(&group)).unwrap_err();
    assert!(matches!(e, PlotError::Invalid { .. }), "{e}");

    let (gt, est, err) = paths();
    let short = &err[..3];
    let panel = TrajectoryPanel {
        title: "seq 07",
        plan: None,
        gt_xy: &gt,
        est_xy: &est,
        errors_m: short,
    };
    let e = trajectory_plot(&keep, &panel).unwrap_err();
    match &e {
        PlotError::LengthMismatch { got, expected, .. } => assert_eq!((*got, *expected), (3, 9)),
        other => panic!("expected a length mismatch, got {other}"),
    }
    assert!(e.to_string().contains("seq 07"), "{e}");
    let nan_est = vec![[f64::NAN, 0.0]; 2];
    let e = trajectory_plot(
        &keep,
        &TrajectoryPanel {
            est_xy: &nan_est,
            errors_m: &[0.1, 0.2],
            ..panel
        },
    )
    .unwrap_err();
    assert!(matches!(e, PlotError::Empty { .. }), "{e}");
    let mut broken = room();
    broken.cells.pop();
    let e = trajectory_plot(
        &keep,
        &TrajectoryPanel {
            plan: Some(&broken),
            errors_m: &err,
            ..panel
        },
    )
    .unwrap_err();
    assert!(matches!(e, PlotError::LengthMismatch { .. }), "{e}");
    let mut zero_cell = room();
    zero_cell.cell = 0.0;
    let e = trajectory_plot(
        &keep,
        &TrajectoryPanel {
            plan: Some(&zero_cell),
            errors_m: &err,
            ..panel
        },
    )
    .unwrap_err();
    assert!(matches!(e, PlotError::Invalid { .. }), "{e}");
    let e = trajectory_grid(&keep, &[]).unwrap_err();
    assert!(matches!(e, PlotError::Empty { .. }), "{e}");
    assert_eq!(std::fs::read(&keep).unwrap(), b"old figure");

    // A directory that does not exist: an I/O error naming the path.
    let missing = dir.path().join("no/such/dir/plot.svg");
    let e = line_plot(&missing, &axes, &series).unwrap_err();
    assert!(
        matches!(e, PlotError::Io { .. }) && e.to_string().contains("plot.svg"),
        "{e}"
    );
}

#[test]
fn large_plans_are_coarsened_before_drawing() {
    // 2000 x 2000 cells of 1 cm: far more cells than pixels. The SVG holds
    // runs of merged cells, so it stays small, and thin walls survive.
    let (width, height) = (2000, 2000);
    let mut cells = vec![PlanCell::Floor; width * height];
    for row in 0..height {
        cells[row * width + 1000] = PlanCell::Obstacle; // a 1 cm wall at x = 10 m
    }
    let plan = FloorPlan {
        min_xy: [0.0, 0.0],
        cell: 0.01,
        width,
        height,
        cells,
    };
    let est = [[5.0, 5.0]];
    let panel = TrajectoryPanel {
        title: "big",
        plan: Some(&plan),
        gt_xy: &[],
        est_xy: &est,
        errors_m: &[0.1],
    };
    let dir = tempfile::tempdir().unwrap();
    let svg_path = dir.path().join("big.svg");
    trajectory_plot(&svg_path, &panel).unwrap();
    let svg_len = std::fs::metadata(&svg_path).unwrap().len();
    assert!(svg_len < 500_000, "SVG of {svg_len} bytes");
    let png_path = dir.path().join("big.png");
    let figure = TrajectoryFigure::new(&png_path, std::slice::from_ref(&panel)).unwrap();
    let l = &write_figure(&png_path, &figure).unwrap()[0];
    let img = read_png(&png_path);
    let wall = to_pixel(l, 10.005, 15.0);
    let dark = (-1..=1).any(|d| pixel(&img, (wall.0 + d, wall.1)).iter().all(|v| *v < 100));
    assert!(dark, "the 1 cm wall is visible at {wall:?}");
}

#[test]
fn tick_labels_are_short() {
    use style::tick_label;
    assert_eq!(tick_label(0.0), "0");
    assert_eq!(tick_label(1024.0), "1024");
    assert_eq!(tick_label(0.1 + 0.2), "0.3");
    assert_eq!(tick_label(-2.5), "-2.5");
    assert_eq!(tick_label(2.5e-5), "2.5e-5");
    assert_eq!(tick_label(3.0e7), "3.0e7");
}

#[test]
fn error_colours_span_viridis_and_ignore_nan() {
    assert_eq!(rgb(error_colour(0.0, 2.0)), [68, 1, 84]);
    assert_eq!(rgb(error_colour(2.0, 2.0)), [254, 232, 37]);
    assert_eq!(rgb(error_colour(5.0, 2.0)), [254, 232, 37]);
    assert_eq!(rgb(error_colour(f64::NAN, 2.0)), [68, 1, 84]);
    assert_eq!(rgb(error_colour(1.0, 0.0)), [68, 1, 84]);
}

#[test]
fn values_near_the_limits_of_f64_are_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.png");
    let huge = vec![Series {
        label: "huge".into(),
        points: vec![(-1e308, 1.0), (1e308, 2.0)],
    }];
    let e = line_plot(&path, &Axes::default(), &huge).unwrap_err();
    assert!(matches!(e, PlotError::Empty { .. }), "{e}");
    let group = BarGroup {
        label: "g".into(),
        bars: vec![("a".into(), 1e308, None), ("b".into(), -1e308, None)],
    };
    let e = bar_plot(&path, &Axes::default(), &[group]).unwrap_err();
    assert!(matches!(e, PlotError::Empty { .. }), "{e}");
    // An error bar reaching past f64::MAX is cut off at the axis instead.
    let group = BarGroup {
        label: "g".into(),
        bars: vec![("a".into(), 1e308, Some(1e308))],
    };
    bar_plot(&dir.path().join("tall.svg"), &Axes::default(), &[group]).unwrap();
    let est = [[-1e308, 0.0], [1e308, 0.0]];
    let panel = TrajectoryPanel {
        title: "far",
        plan: None,
        gt_xy: &[],
        est_xy: &est,
        errors_m: &[0.1, 0.2],
    };
    let e = trajectory_plot(&path, &panel).unwrap_err();
    assert!(matches!(e, PlotError::Invalid { .. }), "{e}");
    // A plan whose width * height overflows is an error, not a panic.
    let plan = FloorPlan {
        min_xy: [0.0, 0.0],
        cell: 0.1,
        width: usize::MAX,
        height: 2,
        cells: vec![PlanCell::Floor],
    };
    assert_eq!(plan.get(5, 1), None);
    let est = [[0.0, 0.0]];
    let panel = TrajectoryPanel {
        plan: Some(&plan),
        est_xy: &est,
        errors_m: &[0.1],
        ..panel
    };
    let e = trajectory_plot(&path, &panel).unwrap_err();
    assert!(matches!(e, PlotError::LengthMismatch { .. }), "{e}");
    assert!(!path.exists());
}

/// A 1 m x 0.5 m floor at z = 0 (row 0) with a wall column at x = 0.5 m
/// (row 1) from the floor to 2.5 m: floor cells are floor, the wall's
/// column an obstacle, and nothing is floor without a floor feature.
#[test]
fn floor_plan_from_a_language_map() {
    use crate::map::{FeatureDb, GridSpec, LanguageMap};
    let db = FeatureDb::from_rows(2, 0.02, vec![1.0, 0.0, 0.0, 1.0]).unwrap();
    let grid = GridSpec {
        resolution: 0.1,
        origin: nalgebra::Vector3::zeros(),
    };
    let mut leaves = Vec::new();
    for x in 0..10 {
        for y in 0..5 {
            leaves.push(([x, y, 0], 0u32));
        }
    }
    for z in 1..25 {
        leaves.push(([5, 2, z], 1u32));
    }
    let map = LanguageMap::from_cells(grid, db, "test", leaves).unwrap();
    let plan = FloorPlan::from_map(&map, Some(&[1.0, 0.0]), 0.9).unwrap();
    assert_eq!((plan.width, plan.height), (10, 5));
    let (c, r) = plan.cell_of(0.55, 0.25).unwrap();
    assert_eq!(plan.get(c, r), Some(PlanCell::Obstacle));
    let (c, r) = plan.cell_of(0.15, 0.25).unwrap();
    assert_eq!(plan.get(c, r), Some(PlanCell::Floor));
    let floors = plan.cells.iter().filter(|c| **c == PlanCell::Floor).count();
    assert_eq!(floors, 49);
    let none = FloorPlan::from_map(&map, None, 0.9).unwrap();
    assert!(none.cells.iter().all(|c| *c != PlanCell::Floor));
}
