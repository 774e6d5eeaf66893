//! The plotting layer: files are written, text is really rendered, odd data
//! does not panic, output is deterministic.

use std::fs;
use std::path::{Path, PathBuf};

use nonholo_lab::plot::{Heatmap, LinePlot, Series, heatmap, line_plot};

/// A fresh, empty directory for one test.
fn out_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("plot-tests")
        .join(name);
    let _ = fs::remove_dir_all(&d);
    fs::create_dir_all(&d).unwrap();
    d
}

/// Decoded 8-bit RGB(A) image: width, height, channels, bytes.
struct Image {
    w: usize,
    h: usize,
    ch: usize,
    px: Vec<u8>,
}

impl Image {
    fn read(path: &Path) -> Image {
        let decoder = png::Decoder::new(fs::File::open(path).unwrap());
        let mut reader = decoder.read_info().unwrap();
        let mut px = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut px).unwrap();
        assert_eq!(info.bit_depth, png::BitDepth::Eight);
        let ch = match info.color_type {
            png::ColorType::Rgb => 3,
            png::ColorType::Rgba => 4,
            other => panic!("unexpected PNG colour type {other:?}"),
        };
        px.truncate(info.buffer_size());
        Image {
            w: info.width as usize,
            h: info.height as usize,
            ch,
            px,
        }
    }

    fn rgb(&self, x: usize, y: usize) -> (u8, u8, u8) {
        let i = (y * self.w + x) * self.ch;
        (self.px[i], self.px[i + 1], self.px[i + 2])
    }

    /// Pixels in rows `rows` satisfying `pred`.
    fn count(&self, rows: std::ops::Range<usize>, pred: impl Fn((u8, u8, u8)) -> bool) -> usize {
        rows.flat_map(|y| (0..self.w).map(move |x| (x, y)))
            .filter(|&(x, y)| pred(self.rgb(x, y)))
            .count()
    }
}

fn dark(c: (u8, u8, u8)) -> bool {
    c.0.max(c.1).max(c.2) < 100
}

fn near(c: (u8, u8, u8), target: (u8, u8, u8), tol: i32) -> bool {
    (c.0 as i32 - target.0 as i32).abs() <= tol
        && (c.1 as i32 - target.1 as i32).abs() <= tol
        && (c.2 as i32 - target.2 as i32).abs() <= tol
}

/// The title is drawn in black 28 px bold text at the top of the figure. A
/// title of n characters inks roughly 100 pixels per character, so a band of
/// the top 50 rows must hold several hundred dark pixels; if the font failed
/// to load, the band holds none. An upper bound (a fifth of the band) rules
/// out a figure that is dark all over.
fn assert_title_rendered(img: &Image) {
    let band = 0..50;
    let n = img.count(band.clone(), dark);
    let total = band.len() * img.w;
    assert!(
        n >= 400,
        "only {n} dark pixels in the title band: text not rendered"
    );
    assert!(
        n < total / 5,
        "{n} of {total} pixels dark in the title band"
    );
}

fn svg_text(path: &Path) -> String {
    let svg = fs::read_to_string(path).unwrap();
    assert!(
        svg.starts_with("<svg"),
        "not an SVG: {}",
        &svg[..svg.len().min(80)]
    );
    svg
}

/// The contents of the `<text>` elements of an SVG, trimmed (plotters puts
/// each on a line of its own).
fn text_elements(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|s| {
            let body = &s[s.find('>')? + 1..];
            Some(body[..body.find("</text>")?].trim().to_string())
        })
        .collect()
}

/// Every file in `dir` is a finished plot: no temporary files are left.
fn assert_no_temp_files(dir: &Path) {
    for e in fs::read_dir(dir).unwrap() {
        let name = e.unwrap().file_name().to_string_lossy().into_owned();
        assert!(!name.contains(".tmp"), "temporary file left behind: {name}");
    }
}

fn convergence_plot() -> LinePlot {
    let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.05).collect();
    let decay: Vec<f64> = t.iter().map(|t| 1e-3 * (-t).exp()).collect();
    // Zeros and a NaN: not drawable on a log axis.
    let mut drift: Vec<f64> = t.iter().map(|t| 1e-9 * (1.0 + t * t)).collect();
    drift[0] = 0.0;
    drift[1] = 0.0;
    drift[100] = f64::NAN;
    LinePlot {
        verticals: Vec::new(),
        title: "Constraint violation of the sleigh".into(),
        x_label: "t [s]".into(),
        y_label: "|g(q, v)| [m/s]".into(),
        log_x: false,
        log_y: true,
        equal_aspect: false,
        y_range: None,
        series: vec![
            Series {
                label: "Chetaev".into(),
                x: t.clone(),
                y: decay,
                pen: None,
            },
            Series {
                label: "vakonomic".into(),
                x: t,
                y: drift,
                pen: None,
            },
        ],
    }
}

fn sweep_heatmap() -> Heatmap {
    let x = vec![0.1, 0.2, 0.4, 0.8, 1.6];
    let y = vec![-1.0, 0.0, 0.5, 3.0];
    let z = y
        .iter()
        .enumerate()
        .map(|(j, yv)| {
            x.iter()
                .enumerate()
                .map(|(i, xv)| {
                    if (i, j) == (2, 1) {
                        None
                    } else {
                        Some(10f64.powf(-xv * 4.0 + yv))
                    }
                })
                .collect()
        })
        .collect();
    Heatmap {
        title: "Energy error after 20 s".into(),
        x_label: "a [m]".into(),
        y_label: "omega0 [rad/s]".into(),
        z_label: "|ΔE| [J]".into(),
        x,
        y,
        z,
        log_z: true,
    }
}

#[test]
fn line_plot_with_log_axis_writes_legible_files() {
    let dir = out_dir("line");
    let paths = line_plot(&convergence_plot(), &dir.join("violation")).unwrap();
    assert_eq!(
        paths,
        vec![dir.join("violation.png"), dir.join("violation.svg")]
    );
    for p in &paths {
        let len = fs::metadata(p).unwrap().len();
        assert!(len > 5_000, "{} has only {len} bytes", p.display());
    }
    assert_no_temp_files(&dir);

    let svg = svg_text(&paths[1]);
    assert!(svg.matches("<text").count() >= 10);
    for s in [
        "Constraint violation of the sleigh",
        "t [s]",
        "|g(q, v)| [m/s]",
        "Chetaev",
        "vakonomic (2 zeros off the log axis, 1 value missing)",
        "1e-9",
    ] {
        assert!(
            text_elements(&svg).iter().any(|t| t == s),
            "SVG lacks the text element {s:?}"
        );
    }

    let img = Image::read(&paths[0]);
    assert_eq!((img.w, img.h), (1200, 800));
    assert_title_rendered(&img);
    // Both curves are drawn in their palette colours (3 px lines over
    // hundreds of pixels).
    let blue = img.count(0..img.h, |c| near(c, (0, 114, 178), 30));
    let vermillion = img.count(0..img.h, |c| near(c, (213, 94, 0), 30));
    assert!(
        blue > 1_000 && vermillion > 1_000,
        "blue {blue}, vermillion {vermillion}"
    );
}

#[test]
fn heatmap_with_missing_cell_writes_legible_files() {
    let dir = out_dir("heat");
    let paths = heatmap(&sweep_heatmap(), &dir.join("sweep")).unwrap();
    for p in &paths {
        assert!(
            fs::metadata(p).unwrap().len() > 5_000,
            "{} too small",
            p.display()
        );
    }
    assert_no_temp_files(&dir);

    let svg = svg_text(&paths[1]);
    for s in [
        "Energy error after 20 s",
        "a [m]",
        "omega0 [rad/s]",
        "|ΔE| [J]",
        "no value: 1 cell",
    ] {
        assert!(
            text_elements(&svg).iter().any(|t| t == s),
            "SVG lacks the text element {s:?}"
        );
    }

    let img = Image::read(&paths[0]);
    assert_title_rendered(&img);
    // The missing cell is a large grey patch; both ends of viridis appear
    // (in the cells and the colour bar).
    let grey = img.count(0..img.h, |c| c == (170, 170, 170));
    assert!(grey > 2_000, "only {grey} grey pixels");
    let dark_purple = img.count(0..img.h, |c| near(c, (0x44, 0x01, 0x54), 12));
    let yellow = img.count(0..img.h, |c| near(c, (0xfd, 0xe7, 0x25), 12));
    assert!(
        dark_purple > 200 && yellow > 200,
        "purple {dark_purple}, yellow {yellow}"
    );
}

#[test]
fn rendering_is_deterministic() {
    let dir = out_dir("determinism");
    let a = line_plot(&convergence_plot(), &dir.join("a")).unwrap();
    let b = line_plot(&convergence_plot(), &dir.join("b")).unwrap();
    assert_eq!(
        fs::read(&a[1]).unwrap(),
        fs::read(&b[1]).unwrap(),
        "line SVG differs"
    );
    assert_eq!(
        fs::read(&a[0]).unwrap(),
        fs::read(&b[0]).unwrap(),
        "line PNG differs"
    );
    let a = heatmap(&sweep_heatmap(), &dir.join("ha")).unwrap();
    let b = heatmap(&sweep_heatmap(), &dir.join("hb")).unwrap();
    assert_eq!(
        fs::read(&a[1]).unwrap(),
        fs::read(&b[1]).unwrap(),
        "heatmap SVG differs"
    );
}

#[test]
fn rewriting_replaces_the_files() {
    let dir = out_dir("rewrite");
    let stem = dir.join("nested").join("fig");
    line_plot(&convergence_plot(), &stem).unwrap();
    let mut p = convergence_plot();
    p.title = "Second version".into();
    let paths = line_plot(&p, &stem).unwrap();
    assert!(text_elements(&svg_text(&paths[1])).contains(&"Second version".to_string()));
    assert_no_temp_files(&dir.join("nested"));
}

fn single(label: &str, x: Vec<f64>, y: Vec<f64>, log_y: bool) -> LinePlot {
    LinePlot {
        verticals: Vec::new(),
        title: format!("Edge case: {label}"),
        x_label: "x [m]".into(),
        y_label: "y [m]".into(),
        log_x: false,
        log_y,
        equal_aspect: false,
        y_range: None,
        series: vec![Series {
            label: label.into(),
            x,
            y,
            pen: None,
        }],
    }
}

/// Documented outcome: odd data still gives both files; when nothing can be
/// drawn the frame carries a note starting "nothing to draw", otherwise the
/// drawable part is shown. Only malformed input is an error.
#[test]
fn edge_cases_do_not_panic() {
    let dir = out_dir("edge");
    let nan = f64::NAN;
    let cases: Vec<(&str, LinePlot, bool)> = vec![
        ("empty", single("empty", vec![], vec![], false), true),
        ("empty-log", single("empty", vec![], vec![], true), true),
        (
            "single",
            single("single point", vec![1.0], vec![2.0], false),
            false,
        ),
        (
            "single-log",
            single("single point", vec![1.0], vec![2.0], true),
            false,
        ),
        (
            "constant",
            single("constant", vec![0.0, 1.0, 2.0], vec![3.0; 3], false),
            false,
        ),
        (
            "constant-log",
            single("constant", vec![0.0, 1.0, 2.0], vec![3.0; 3], true),
            false,
        ),
        (
            "zeros",
            single("zeros", vec![0.0, 1.0], vec![0.0, 0.0], false),
            false,
        ),
        (
            "all-nan",
            single("all NaN", vec![nan; 4], vec![nan; 4], false),
            true,
        ),
        (
            "all-nonpositive-log",
            single("nonpositive", vec![1.0, 2.0], vec![0.0, -1.0], true),
            true,
        ),
        (
            "infinities",
            single(
                "inf",
                vec![0.0, 1.0, 2.0],
                vec![f64::INFINITY, 1.0, f64::NEG_INFINITY],
                false,
            ),
            false,
        ),
        (
            "huge",
            single("huge", vec![-1e300, 1e300], vec![1e-300, 1e300], true),
            false,
        ),
        (
            "no-series",
            LinePlot {
                title: "nothing".into(),
                x_label: "x [m]".into(),
                y_label: "y [m]".into(),
                ..Default::default()
            },
            true,
        ),
    ];
    for (name, plot, empty) in cases {
        let paths = line_plot(&plot, &dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let svg = svg_text(&paths[1]);
        assert_eq!(
            svg.contains("nothing to draw"),
            empty,
            "{name}: note presence"
        );
        assert!(Image::read(&paths[0]).w == 1200, "{name}");
    }
    let mut trajectory = single("circle", vec![], vec![], false);
    for k in 0..=100 {
        let a = k as f64 * std::f64::consts::TAU / 100.0;
        trajectory.series[0].x.push(10.0 + 3.0 * a.cos());
        trajectory.series[0].y.push(0.5 * a.sin());
    }
    trajectory.equal_aspect = true;
    line_plot(&trajectory, &dir.join("equal-aspect")).unwrap();

    // More series than palette colours: the second round is dashed.
    let mut many = single("s0", vec![], vec![], true);
    many.series = (0..9)
        .map(|k| Series {
            label: format!("h = 1e-{k}"),
            x: (1..=50).map(f64::from).collect(),
            y: (1..=50).map(|i| 10f64.powi(-k) / f64::from(i)).collect(),
            pen: None,
        })
        .collect();
    many.log_x = true;
    let paths = line_plot(&many, &dir.join("many-series")).unwrap();
    let svg = svg_text(&paths[1]);
    assert!(text_elements(&svg).contains(&"h = 1e-8".to_string()));

    let bad = single("bad", vec![1.0, 2.0], vec![1.0], false);
    let err = line_plot(&bad, &dir.join("bad")).unwrap_err();
    assert!(err.contains("x has 2 values but y has 1"), "{err}");
    assert!(!dir.join("bad.png").exists());
}

#[test]
fn heatmap_edge_cases_do_not_panic() {
    let dir = out_dir("heat-edge");
    let base = Heatmap {
        title: "Edge".into(),
        x_label: "x [m]".into(),
        y_label: "y [m]".into(),
        z_label: "z [m]".into(),
        ..Default::default()
    };
    let cases: Vec<(&str, Heatmap, bool)> = vec![
        ("empty", base.clone(), true),
        (
            "one-cell",
            Heatmap {
                x: vec![1.0],
                y: vec![2.0],
                z: vec![vec![Some(3.0)]],
                ..base.clone()
            },
            false,
        ),
        (
            "all-missing",
            Heatmap {
                x: vec![1.0, 2.0],
                y: vec![0.0],
                z: vec![vec![None, Some(f64::NAN)]],
                ..base.clone()
            },
            true,
        ),
        (
            "constant-log",
            Heatmap {
                x: vec![3.0, 2.0, 1.0],
                y: vec![0.0, 1e-3],
                z: vec![vec![Some(5.0); 3], vec![Some(5.0), Some(0.0), Some(-1.0)]],
                log_z: true,
                ..base.clone()
            },
            false,
        ),
    ];
    for (name, h, empty) in cases {
        let paths = heatmap(&h, &dir.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let svg = svg_text(&paths[1]);
        assert_eq!(
            svg.contains("nothing to draw"),
            empty,
            "{name}: note presence"
        );
    }
    let ragged = Heatmap {
        x: vec![1.0, 2.0],
        y: vec![0.0],
        z: vec![vec![Some(1.0)]],
        ..base.clone()
    };
    assert!(
        heatmap(&ragged, &dir.join("ragged"))
            .unwrap_err()
            .contains("row 0 has 1 values")
    );
    let unsorted = Heatmap {
        x: vec![1.0, 3.0, 2.0],
        y: vec![0.0],
        z: vec![vec![None; 3]],
        ..base
    };
    assert!(
        heatmap(&unsorted, &dir.join("unsorted"))
            .unwrap_err()
            .contains("strictly")
    );
}

/// A series with a pen is drawn in its colour, whatever its position: the
/// vermillion of palette entry 1 as the first series, and the blue of entry
/// 0 (the first series' default) nowhere.
#[test]
fn a_pen_sets_the_colour_of_its_series() {
    use nonholo_lab::plot::{Dash, Pen};
    let dir = out_dir("pen");
    let mut p = single("A", vec![0.0, 1.0, 2.0], vec![1.0, 2.0, 1.5], false);
    p.series[0].pen = Some(Pen {
        colour: 1,
        dash: Dash::Dashed,
    });
    let paths = line_plot(&p, &dir.join("pen")).unwrap();
    let svg = std::fs::read_to_string(&paths[1]).unwrap().to_uppercase();
    assert!(svg.contains("#D55E00"), "vermillion missing");
    assert!(!svg.contains("#0072B2"), "blue drawn");
}

/// A curve that turns sharply at every point (round-off noise on a log
/// axis) stays inside the plot: no pixel of its colour in the band of the
/// title or below the x tick labels (the bitmap backend's miter joins used
/// to throw spikes across both).
#[test]
fn sharp_turns_stay_inside_the_plot() {
    let dir = out_dir("spikes");
    let x: Vec<f64> = (0..2000).map(|i| f64::from(i) * 0.05).collect();
    let y: Vec<f64> = (0..2000)
        .map(|i| if i % 2 == 0 { 1e-14 } else { 1e-9 })
        .collect();
    let p = single("zigzag", x, y, true);
    let paths = line_plot(&p, &dir.join("zigzag")).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&paths[0]).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let (w, h) = (info.width as usize, info.height as usize);
    let blue = [0u8, 114, 178];
    let is_blue = |row: usize, col: usize| {
        let i = (row * w + col) * 3;
        buf[i..i + 3] == blue
    };
    for row in (0..45).chain(h - 40..h) {
        for col in 0..w {
            assert!(
                !is_blue(row, col),
                "series colour at row {row}, column {col}"
            );
        }
    }
}

/// Every axis says its unit: a label without one in brackets is refused,
/// naming it, for line plots and heat maps alike.
#[test]
fn an_axis_without_a_unit_is_refused() {
    let dir = out_dir("units");
    let mut p = convergence_plot();
    p.y_label = "error".into();
    let e = line_plot(&p, &dir.join("no-unit")).unwrap_err();
    assert!(e.contains("axis label `error` has no unit"), "{e}");
    p.y_label = "error []".into();
    assert!(line_plot(&p, &dir.join("empty-unit")).is_err());
    p.y_label = "c [–]".into();
    line_plot(&p, &dir.join("pure-number")).unwrap();
    let mut h = sweep_heatmap();
    h.z_label = "distance".into();
    let e = heatmap(&h, &dir.join("heat-no-unit")).unwrap_err();
    assert!(e.contains("`distance`"), "{e}");
    assert!(!dir.join("no-unit.png").exists() && !dir.join("heat-no-unit.png").exists());
}
