//! Figures for papers: line plots and heatmaps drawn from plain data, each
//! written as `<stem>.png` (1200×800 px) and `<stem>.svg`.
//!
//! This module knows nothing about experiments or mechanics: it takes
//! numbers, labels and units and writes files.
//!
//! Conventions shared by both kinds of figure:
//! - Text uses the DejaVu Sans font compiled into the binary (registered once
//!   under the family name `sans-serif`), so PNG text renders on a machine
//!   without system fonts; the SVG keeps real `<text>` elements.
//! - Sizes are chosen to stay legible when the figure is shrunk to a column
//!   width: em sizes of about title 28 px, axis labels 24 px, legend 22 px,
//!   ticks 20 px (plotters sizes a font by its ascent plus descent, about
//!   1.17 em for DejaVu, hence the larger constants below); lines 3 px.
//! - Log axes show only finite positive values; tick labels on log axes are
//!   in scientific notation (`1e-6`).
//! - What cannot be drawn is not an error: empty, all-NaN or all-nonpositive
//!   (on a log axis) data gives a frame with a note "nothing to draw: …" in
//!   the middle, and the files are still written. `Err` is returned only for
//!   malformed input (mismatched lengths, a non-monotone heatmap grid, a
//!   stem without a file name) and for I/O failures.
//! - Each file is rendered to a temporary file in the target directory,
//!   flushed to disk and renamed over the target, so a crash never leaves a
//!   half-written plot. The target directory is created if missing.
//! - Output is deterministic: identical input gives byte-identical files.

use std::ffi::OsString;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::element::{DashedPathElement, MultiLineText};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{FontStyle, register_font};

/// One curve of a [`LinePlot`]: the points `(x[i], y[i])` joined in order.
///
/// Points that cannot be drawn (NaN, ±inf, or non-positive on a log axis)
/// break the curve into separate pieces; the legend then says how many
/// points were left out. Series with at most 40 points, and isolated points
/// between gaps, are also drawn as dots.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// Abscissae, same length as `y`.
    pub x: Vec<f64>,
    /// Ordinates, same length as `x`.
    pub y: Vec<f64>,
}

/// A line plot: one or more [`Series`] on shared axes, with a legend.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LinePlot {
    /// Text above the plot.
    pub title: String,
    /// Quantity and unit of the horizontal axis, e.g. `"t [s]"`.
    pub x_label: String,
    /// Quantity and unit of the vertical axis.
    pub y_label: String,
    /// Logarithmic horizontal axis.
    pub log_x: bool,
    /// Logarithmic vertical axis.
    pub log_y: bool,
    /// One data unit has the same length on both axes (for trajectories in
    /// the plane). Ignored when either axis is logarithmic.
    pub equal_aspect: bool,
    /// The curves, drawn in order; colours follow the Okabe–Ito palette, and
    /// from the eighth series on the colours repeat with dashed lines.
    pub series: Vec<Series>,
}

/// A heatmap: a colour per cell of a (possibly non-uniform) grid, with a
/// colour bar.
///
/// Cell `(i, j)` is centred on `(x[i], y[j])`; its edges lie halfway between
/// neighbouring grid values, and the outer cells extend as far beyond their
/// centre as towards their neighbour. Grids must be finite and strictly
/// monotone (increasing or decreasing).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Heatmap {
    /// Text above the plot.
    pub title: String,
    /// Quantity and unit of the horizontal axis.
    pub x_label: String,
    /// Quantity and unit of the vertical axis.
    pub y_label: String,
    /// Quantity and unit shown by the colour, written along the colour bar.
    pub z_label: String,
    /// Cell centres along the horizontal axis.
    pub x: Vec<f64>,
    /// Cell centres along the vertical axis.
    pub y: Vec<f64>,
    /// `z[j][i]` is the value at `(x[i], y[j])`: `y.len()` rows of
    /// `x.len()` values. `None` (a failed or missing run), NaN and ±inf are
    /// drawn in grey with a cross, and counted under the colour bar.
    pub z: Vec<Vec<Option<f64>>>,
    /// Logarithmic colour scale; non-positive values are then drawn like
    /// missing ones (and counted separately under the colour bar).
    pub log_z: bool,
}

/// Draws `p` and writes `<stem>.png` and `<stem>.svg`; returns both paths
/// (PNG first).
///
/// The extensions are appended to `stem` (a stem `out/h=0.1` gives
/// `out/h=0.1.png`). Empty or undrawable data gives a frame with a note, not
/// an error; see the module documentation.
pub fn line_plot(p: &LinePlot, stem: &Path) -> Result<Vec<PathBuf>, String> {
    let data = LineData::new(p)?;
    write_outputs(
        stem,
        |root| draw_line_plot(&root, p, &data),
        |root| draw_line_plot(&root, p, &data),
    )
}

/// Draws `h` as coloured cells with a colour bar and writes `<stem>.png`
/// and `<stem>.svg`; returns both paths (PNG first).
///
/// The extensions are appended to `stem`. An empty grid or one without a
/// drawable value gives a frame with a note, not an error; see the module
/// documentation.
pub fn heatmap(h: &Heatmap, stem: &Path) -> Result<Vec<PathBuf>, String> {
    let data = HeatData::new(h)?;
    write_outputs(
        stem,
        |root| draw_heatmap(&root, h, &data),
        |root| draw_heatmap(&root, h, &data),
    )
}

// ---------------------------------------------------------------------------
// Style

const SIZE: (u32, u32) = (1200, 800);
const FONT: &str = "sans-serif";
const TITLE_PX: f64 = 33.0;
const LABEL_PX: f64 = 28.0;
const LEGEND_PX: f64 = 26.0;
const TICK_PX: f64 = 24.0;
const NOTE_PX: f64 = 26.0;
const LINE_PX: u32 = 3;
const MARKER_PX: i32 = 5;
/// Series with at most this many points also get a dot per point.
const MARKER_MAX_POINTS: usize = 40;
const TICK_MARK_PX: i32 = 6;
/// Width of the legend's line sample, including the gap before the text.
const LEGEND_SAMPLE_PX: u32 = 56;
const LEGEND_MARGIN_PX: u32 = 10;
/// Width of the heatmap's colour bar.
const COLOUR_BAR_PX: u32 = 50;
/// Side of the grey square explaining missing heatmap cells.
const SWATCH_PX: u32 = 26;

/// Okabe & Ito's colour-blind-safe palette, without its yellow (too pale on
/// white): blue, vermillion, bluish green, reddish purple, orange, sky blue,
/// black.
const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
];

/// Viridis (van der Walt & Smith, matplotlib's default), sampled at ten
/// evenly spaced points and interpolated linearly in between.
const VIRIDIS: [(u8, u8, u8); 10] = [
    (0x44, 0x01, 0x54),
    (0x48, 0x28, 0x78),
    (0x3e, 0x4a, 0x89),
    (0x31, 0x68, 0x8e),
    (0x26, 0x82, 0x8e),
    (0x1f, 0x9e, 0x89),
    (0x35, 0xb7, 0x79),
    (0x6d, 0xcd, 0x59),
    (0xb4, 0xde, 0x2c),
    (0xfd, 0xe7, 0x25),
];

/// Fill of heatmap cells without a drawable value.
const MISSING_FILL: RGBColor = RGBColor(170, 170, 170);
/// Cross drawn over heatmap cells without a drawable value.
const MISSING_CROSS: RGBColor = RGBColor(90, 90, 90);

fn viridis(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = t * (VIRIDIS.len() - 1) as f64;
    let k = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let f = s - k as f64;
    let (a, b) = (VIRIDIS[k], VIRIDIS[k + 1]);
    let mix = |u: u8, v: u8| (u as f64 + f * (v as f64 - u as f64)).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

fn series_colour(k: usize) -> RGBColor {
    PALETTE[k % PALETTE.len()]
}

fn series_dashed(k: usize) -> bool {
    (k / PALETTE.len()) % 2 == 1
}

fn text(px: f64) -> TextStyle<'static> {
    (FONT, px).into_font().into()
}

fn title_text() -> TextStyle<'static> {
    (FONT, TITLE_PX, FontStyle::Bold).into_font().into()
}

/// Registers DejaVu Sans (regular and bold) as `sans-serif`, once per
/// process.
fn ensure_font() -> Result<(), String> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
                .and_then(|_| register_font(FONT, FontStyle::Bold, dejavu::sans::bold()))
                .map_err(|_| "cannot load the bundled DejaVu Sans font".to_string())
        })
        .clone()
}

fn draw_err(e: impl std::fmt::Display) -> String {
    format!("drawing the plot failed: {e}")
}

// ---------------------------------------------------------------------------
// Axes and ticks

/// An axis range in plot coordinates: the data value itself, or its base-10
/// logarithm on a log axis.
#[derive(Debug, Clone, Copy)]
struct Axis {
    log: bool,
    lo: f64,
    hi: f64,
}

/// Tick positions (plot coordinates) with their labels, and positions of
/// the fainter grid lines between them.
struct Ticks {
    bold: Vec<f64>,
    labels: Vec<String>,
    light: Vec<f64>,
}

/// A linear plotters coordinate (in plot coordinates) with our own tick
/// positions: labelled ticks with grid lines, and fainter grid lines.
struct AxisCoord {
    linear: RangedCoordf64,
    bold: Vec<f64>,
    light: Vec<f64>,
}

impl Ranged for AxisCoord {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.linear.map(value, limit)
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        self.linear.range()
    }
}

/// Maps a data value to plot coordinates; `None` if it cannot be drawn.
fn to_plot(v: f64, log: bool) -> Option<f64> {
    if !v.is_finite() {
        None
    } else if log {
        (v > 0.0).then(|| v.log10())
    } else {
        Some(v)
    }
}

impl Axis {
    /// The smallest range holding `values` (plot coordinates), widened by
    /// `margin` times its length on each side. A single value gets a range
    /// around it (±half a decade on a log axis); no value gives 0..1 (1..10
    /// on a log axis).
    fn fit(values: impl IntoIterator<Item = f64>, log: bool, margin: f64) -> Axis {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        if lo > hi {
            return Axis {
                log,
                lo: 0.0,
                hi: 1.0,
            };
        }
        let scale = lo.abs().max(hi.abs());
        if hi - lo <= 1e-12 * scale || hi == lo {
            let pad = if log {
                0.5
            } else if scale > 0.0 {
                0.1 * scale
            } else {
                1.0
            };
            return Axis {
                log,
                lo: lo - pad,
                hi: hi + pad,
            };
        }
        let m = margin * (hi - lo);
        if (hi - lo).is_finite() && (lo - m).is_finite() && (hi + m).is_finite() {
            lo -= m;
            hi += m;
        }
        Axis { log, lo, hi }
    }

    fn span(&self) -> f64 {
        self.hi - self.lo
    }

    /// Widens the range symmetrically to length `span`.
    fn widen_to(&mut self, span: f64) {
        if span > self.span() && span.is_finite() {
            let c = 0.5 * (self.lo + self.hi);
            self.lo = c - 0.5 * span;
            self.hi = c + 0.5 * span;
        }
    }

    /// Range with custom ticks, for plotters.
    fn coord(&self) -> AxisCoord {
        let t = self.ticks();
        AxisCoord {
            linear: (self.lo..self.hi).into(),
            bold: t.bold,
            light: t.light,
        }
    }

    fn ticks(&self) -> Ticks {
        if self.log {
            log_ticks(self.lo, self.hi)
        } else {
            let (bold, step) = linear_ticks(self.lo, self.hi, 8.0);
            let sci = use_sci(self.lo, self.hi);
            let labels = bold.iter().map(|&v| fmt_linear(v, step, sci)).collect();
            Ticks {
                bold,
                labels,
                light: Vec::new(),
            }
        }
    }
}

/// A round step (1, 2 or 5 times a power of ten) near `raw`.
fn nice_step(raw: f64) -> f64 {
    let p = 10f64.powf(raw.log10().floor());
    let m = raw / p;
    let n = if m <= 1.0 {
        1.0
    } else if m <= 2.0 {
        2.0
    } else if m <= 5.0 {
        5.0
    } else {
        10.0
    };
    n * p
}

/// Multiples of a round step inside `lo..=hi`, about `target` of them, and
/// the step. Empty for a degenerate range.
fn linear_ticks(lo: f64, hi: f64, target: f64) -> (Vec<f64>, f64) {
    let span = hi - lo;
    if !(span.is_finite() && span > 0.0) {
        return (Vec::new(), 0.0);
    }
    let step = nice_step(span / target);
    if !(step.is_finite() && step > 0.0) {
        return (Vec::new(), 0.0);
    }
    let mut out = Vec::new();
    let mut k = (lo / step).ceil();
    while k * step <= hi && out.len() < 100 {
        let v = k * step;
        out.push(if v.abs() < 1e-9 * step { 0.0 } else { v });
        k += 1.0;
    }
    (out, step)
}

fn use_sci(lo: f64, hi: f64) -> bool {
    let m = lo.abs().max(hi.abs());
    !(1e-3..1e5).contains(&m) && m > 0.0
}

/// A tick label on a linear axis: as many decimals as the step needs, in
/// scientific notation for very large or small numbers.
fn fmt_linear(v: f64, step: f64, sci: bool) -> String {
    let step_exp = step.log10().floor();
    if sci {
        let digits = (v.abs().log10().floor() - step_exp).clamp(0.0, 12.0) as usize;
        fmt_sci(v, digits + 1)
    } else {
        let decimals = (-step_exp).clamp(0.0, 12.0) as usize;
        format!("{v:.decimals$}")
    }
}

/// `v` in scientific notation with at most `sig` significant digits and no
/// trailing zeros: `1e-6`, `2.5e3`.
fn fmt_sci(v: f64, sig: usize) -> String {
    if v == 0.0 {
        return "0".to_string();
    }
    let s = format!("{:.*e}", sig.max(1) - 1, v);
    match s.split_once('e') {
        Some((m, e)) if m.contains('.') => {
            format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
        }
        _ => s,
    }
}

/// Ticks on a log axis whose range is `lo..hi` in decades (log10 values).
///
/// Three or more decades: labelled decades (every 2nd, 5th, 10th, ... if
/// there are more than eight), with grid lines at 2..9 times each decade. Fewer: 1, 2 and 5
/// times each decade, or every integer multiple, or (for a range within a
/// fraction of a decade) round linear steps.
fn log_ticks(lo: f64, hi: f64) -> Ticks {
    let mut t = Ticks {
        bold: Vec::new(),
        labels: Vec::new(),
        light: Vec::new(),
    };
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return t;
    }
    let in_range = |p: f64| p >= lo - 1e-9 && p <= hi + 1e-9;
    let (d0, d1) = (lo.ceil(), hi.floor());
    let decades = d1 - d0 + 1.0;
    if decades >= 3.0 {
        // Label every 1, 2, 5, 10, 20, ... decades; grid lines at the other
        // decades unless they would blur into a grey band.
        let every = if decades <= 8.0 {
            1.0
        } else {
            nice_step(decades / 8.0)
        };
        let mut d = lo.floor();
        while d <= hi.ceil() {
            if in_range(d) {
                if d.rem_euclid(every) == 0.0 {
                    t.bold.push(d);
                } else if decades <= 40.0 {
                    t.light.push(d);
                }
            }
            if every == 1.0 {
                for m in 2..10 {
                    let p = d + (m as f64).log10();
                    if in_range(p) {
                        t.light.push(p);
                    }
                }
            }
            d += 1.0;
        }
    } else {
        for mults in [
            &[1.0, 2.0, 5.0][..],
            &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0][..],
        ] {
            t.bold.clear();
            t.light.clear();
            let mut d = lo.floor();
            while d <= hi.ceil() {
                for m in 1..10 {
                    let p = d + (m as f64).log10();
                    if in_range(p) {
                        if mults.contains(&(m as f64)) {
                            t.bold.push(p);
                        } else {
                            t.light.push(p);
                        }
                    }
                }
                d += 1.0;
            }
            if t.bold.len() >= 3 {
                break;
            }
        }
        if t.bold.len() < 3 {
            // Within a fraction of a decade: round steps of the value itself.
            let (a, b) = (10f64.powf(lo), 10f64.powf(hi));
            let (vals, step) = linear_ticks(a, b, 6.0);
            let labels = vals
                .iter()
                .map(|&v| {
                    let digits = (v.abs().log10().floor() - step.log10().floor()).clamp(0.0, 12.0);
                    fmt_sci(v, digits as usize + 1)
                })
                .collect();
            return Ticks {
                bold: vals.iter().map(|v| v.log10()).collect(),
                labels,
                light: Vec::new(),
            };
        }
    }
    t.labels = t.bold.iter().map(|&p| fmt_sci(10f64.powf(p), 3)).collect();
    t
}

/// The label of the bold tick at plot coordinate `v`.
fn tick_label(t: &Ticks, v: f64) -> String {
    t.bold
        .iter()
        .zip(&t.labels)
        .min_by(|a, b| (a.0 - v).abs().total_cmp(&(b.0 - v).abs()))
        .map(|(_, l)| l.clone())
        .unwrap_or_default()
}

fn max_label_width<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    labels: &[String],
) -> Result<u32, String> {
    let style = text(TICK_PX);
    let mut w = 0;
    for l in labels {
        w = w.max(area.estimate_text_size(l, &style).map_err(draw_err)?.0);
    }
    Ok(w)
}

/// Sizes of the bottom (x) and left (y) label areas: tick marks, tick
/// labels, a gap and the axis description.
fn label_areas<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    xa: &Axis,
    ya: &Axis,
) -> Result<(u32, u32), String> {
    let tick_h = area
        .estimate_text_size("0", &text(TICK_PX))
        .map_err(draw_err)?
        .1;
    let desc = LABEL_PX as u32 + 8;
    let x_area = 2 * TICK_MARK_PX as u32 + tick_h + 12 + desc;
    let y_w = max_label_width(area, &ya.ticks().labels)?;
    let y_area = 2 * TICK_MARK_PX as u32 + y_w + 14 + desc;
    // Keep room for the first x tick label, centred under the y axis.
    let x_first = max_label_width(
        area,
        &xa.ticks().labels.into_iter().take(1).collect::<Vec<_>>(),
    )?;
    Ok((x_area, y_area.max(x_first / 2 + 10)))
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<AxisCoord, AxisCoord>>;

fn build_chart<'a, DB: DrawingBackend>(
    area: &'a DrawingArea<DB, Shift>,
    xa: &Axis,
    ya: &Axis,
    (x_area, y_area): (u32, u32),
    right_margin: u32,
) -> Result<Chart<'a, DB>, String> {
    ChartBuilder::on(area)
        .margin_top(12)
        .margin_left(8)
        .margin_bottom(8)
        .margin_right(right_margin)
        .x_label_area_size(x_area)
        .y_label_area_size(y_area)
        .build_cartesian_2d(xa.coord(), ya.coord())
        .map_err(draw_err)
}

/// Grid, axes, tick labels and axis descriptions, and a frame around the
/// plotting area.
fn draw_axes<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    xa: &Axis,
    ya: &Axis,
    x_label: &str,
    y_label: &str,
    grid: bool,
) -> Result<(), String> {
    let (xt, yt) = (xa.ticks(), ya.ticks());
    let fx = |v: &f64| tick_label(&xt, *v);
    let fy = |v: &f64| tick_label(&yt, *v);
    let mut mesh = chart.configure_mesh();
    mesh.x_label_formatter(&fx)
        .y_label_formatter(&fy)
        .x_desc(x_label)
        .y_desc(y_label)
        .axis_desc_style(text(LABEL_PX))
        .label_style(text(TICK_PX))
        .axis_style(BLACK.stroke_width(2))
        .set_all_tick_mark_size(TICK_MARK_PX)
        .bold_line_style(BLACK.mix(0.18).stroke_width(1))
        .light_line_style(BLACK.mix(0.07).stroke_width(1));
    if !grid {
        mesh.disable_mesh();
    }
    mesh.draw().map_err(draw_err)?;
    chart
        .plotting_area()
        .draw(&Rectangle::new(
            [(xa.lo, ya.hi), (xa.hi, ya.lo)],
            BLACK.stroke_width(1),
        ))
        .map_err(draw_err)?;
    Ok(())
}

/// A note in the middle of `area`, on a white box.
fn draw_note<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, note: &str) -> Result<(), String> {
    let style = text(NOTE_PX).pos(Pos::new(HPos::Center, VPos::Center));
    let (w, h) = area.dim_in_pixel();
    let (tw, th) = area.estimate_text_size(note, &style).map_err(draw_err)?;
    let (cx, cy) = (w as i32 / 2, h as i32 / 2);
    let (hw, hh) = (tw as i32 / 2 + 12, th as i32 / 2 + 10);
    area.draw(&Rectangle::new(
        [(cx - hw, cy - hh), (cx + hw, cy + hh)],
        WHITE.mix(0.9).filled(),
    ))
    .map_err(draw_err)?;
    area.draw(&Rectangle::new(
        [(cx - hw, cy - hh), (cx + hw, cy + hh)],
        BLACK.mix(0.5),
    ))
    .map_err(draw_err)?;
    area.draw_text(note, &style, (cx, cy)).map_err(draw_err)
}

// ---------------------------------------------------------------------------
// Line plots

struct SeriesData {
    /// Legend text, with a note on points left out.
    label: String,
    /// Maximal runs of drawable points, in plot coordinates.
    runs: Vec<Vec<(f64, f64)>>,
    markers: bool,
}

struct LineData {
    series: Vec<SeriesData>,
    x: Axis,
    y: Axis,
    /// Why nothing is drawn, if nothing is.
    empty_note: Option<String>,
}

impl LineData {
    fn new(p: &LinePlot) -> Result<LineData, String> {
        let mut series = Vec::new();
        for s in &p.series {
            if s.x.len() != s.y.len() {
                return Err(format!(
                    "series '{}': x has {} values but y has {}",
                    s.label,
                    s.x.len(),
                    s.y.len()
                ));
            }
            let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
            let mut run = Vec::new();
            for (&x, &y) in s.x.iter().zip(&s.y) {
                match (to_plot(x, p.log_x), to_plot(y, p.log_y)) {
                    (Some(px), Some(py)) => run.push((px, py)),
                    _ => {
                        if !run.is_empty() {
                            runs.push(std::mem::take(&mut run));
                        }
                    }
                }
            }
            if !run.is_empty() {
                runs.push(run);
            }
            let drawn: usize = runs.iter().map(Vec::len).sum();
            let hidden = s.x.len() - drawn;
            let label = match (hidden, drawn) {
                (0, _) => s.label.clone(),
                (_, 0) => format!("{} (no drawable point)", s.label),
                (1, _) => format!("{} (1 point not shown)", s.label),
                (n, _) => format!("{} ({n} points not shown)", s.label),
            };
            series.push(SeriesData {
                label,
                runs,
                markers: s.x.len() <= MARKER_MAX_POINTS,
            });
        }
        let points = || series.iter().flat_map(|s| s.runs.iter().flatten());
        let x = Axis::fit(points().map(|p| p.0), p.log_x, 0.03);
        let y = Axis::fit(points().map(|p| p.1), p.log_y, 0.05);
        let empty_note = if points().next().is_some() {
            None
        } else if series.is_empty() {
            Some("nothing to draw: no series".to_string())
        } else if p.log_x || p.log_y {
            Some("nothing to draw: no finite positive values for the log axis".to_string())
        } else {
            Some("nothing to draw: no finite values".to_string())
        };
        Ok(LineData {
            series,
            x,
            y,
            empty_note,
        })
    }
}

fn draw_line_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    p: &LinePlot,
    data: &LineData,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(draw_err)?;
    let area = root
        .margin(8, 8, 8, 8)
        .titled(&p.title, title_text())
        .map_err(draw_err)?;
    let right = 40;
    let (mut xa, mut ya) = (data.x, data.y);
    let mut areas = label_areas(&area, &xa, &ya)?;
    if p.equal_aspect && !p.log_x && !p.log_y {
        // Thrice: the tick labels (hence the plotting area) depend on the ranges.
        for _ in 0..3 {
            let chart = build_chart(&area, &data.x, &data.y, areas, right)?;
            let (pw, ph) = chart.plotting_area().dim_in_pixel();
            let per_px = (data.x.span() / pw.max(1) as f64).max(data.y.span() / ph.max(1) as f64);
            (xa, ya) = (data.x, data.y);
            xa.widen_to(per_px * pw as f64);
            ya.widen_to(per_px * ph as f64);
            areas = label_areas(&area, &xa, &ya)?;
        }
    }
    // A legend that would cover curves wherever it sits inside the plot goes
    // beside it (a column to the right) or under it instead.
    let mut legend_at = None;
    let mut outside = None;
    if !data.series.is_empty() {
        let chart = build_chart(&area, &xa, &ya, areas, right)?;
        let spot = legend_position(&chart, &xa, &ya, data)?;
        legend_at = Some(spot.at);
        if spot.covered > 0 {
            legend_at = None;
            let (aw, ah) = area.dim_in_pixel();
            let w = spot.size.0;
            outside = Some(if (w as f64) <= 0.4 * aw as f64 {
                // A column to the right of the plot.
                let (plot, legend) = area.split_horizontally(aw as i32 - w - 16);
                (plot, legend, 1)
            } else {
                // Under the plot: two columns (in the smaller tick font) if
                // the longest entry fits in half the width, else one.
                let half = (w as f64 * TICK_PX / LEGEND_PX) <= aw as f64 / 2.0 - 8.0;
                let columns = if half { 2 } else { 1 };
                let rows = data.series.len().div_ceil(columns) as i32;
                let h = rows * legend_row_px() + 16;
                let (plot, legend) = area.split_vertically(ah as i32 - h);
                (plot, legend, columns)
            });
        }
    }
    let plot_area = outside.as_ref().map(|(p, _, _)| p).unwrap_or(&area);
    let margin = if outside.is_some() { 24 } else { right };
    let mut chart = build_chart(plot_area, &xa, &ya, areas, margin)?;
    if let Some((_, legend_area, columns)) = &outside {
        draw_outside_legend(legend_area, data, *columns)?;
    }
    draw_axes(&mut chart, &xa, &ya, &p.x_label, &p.y_label, true)?;

    for (k, s) in data.series.iter().enumerate() {
        let colour = series_colour(k);
        let style = colour.stroke_width(LINE_PX);
        for run in &s.runs {
            if run.len() >= 2 {
                if series_dashed(k) {
                    chart
                        .draw_series(DashedLineSeries::new(run.iter().copied(), 14, 8, style))
                        .map_err(draw_err)?;
                } else {
                    chart
                        .draw_series(LineSeries::new(run.iter().copied(), style))
                        .map_err(draw_err)?;
                }
            }
            if s.markers || run.len() == 1 {
                chart
                    .draw_series(
                        run.iter()
                            .map(|&q| Circle::new(q, MARKER_PX, colour.filled())),
                    )
                    .map_err(draw_err)?;
            }
        }
    }
    // Legend entries, one per series even if nothing of it could be drawn.
    for (k, s) in data.series.iter().enumerate() {
        let colour = series_colour(k);
        let style = colour.stroke_width(LINE_PX);
        let r = if s.markers { MARKER_PX } else { 0 };
        let len = LEGEND_SAMPLE_PX as i32 - 14;
        let anno = chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(draw_err)?;
        anno.label(s.label.clone());
        if series_dashed(k) {
            anno.legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + DashedPathElement::new(vec![(0, 0), (len, 0)], 9, 5, style)
                    + Circle::new((len / 2, 0), r, colour.filled())
            });
        } else {
            anno.legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (len, 0)], style)
                    + Circle::new((len / 2, 0), r, colour.filled())
            });
        }
    }
    if let Some((lx, ly)) = legend_at {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::Coordinate(lx, ly))
            .margin(LEGEND_MARGIN_PX)
            .legend_area_size(LEGEND_SAMPLE_PX)
            .label_font(text(LEGEND_PX))
            .background_style(WHITE.mix(0.88).filled())
            .border_style(BLACK.mix(0.45))
            .draw()
            .map_err(draw_err)?;
    }
    if let Some(note) = &data.empty_note {
        draw_note(&chart.plotting_area().strip_coord_spec(), note)?;
    }
    root.present().map_err(draw_err)
}

fn legend_row_px() -> i32 {
    (LEGEND_PX * 1.25) as i32
}

/// The legend as entries (sample line, dot, text) in `columns` columns
/// filled top to bottom, in `area` outside the plot, for plots with too
/// many series to keep it inside.
fn draw_outside_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    data: &LineData,
    columns: usize,
) -> Result<(), String> {
    let style = text(if columns > 1 { TICK_PX } else { LEGEND_PX });
    let len = LEGEND_SAMPLE_PX as i32 - 14;
    let row = legend_row_px();
    let top = 12 + row / 2;
    let per_column = data.series.len().div_ceil(columns.max(1));
    let (aw, _) = area.dim_in_pixel();
    let col_w = aw as i32 / columns.max(1) as i32;
    for (k, s) in data.series.iter().enumerate() {
        let y = top + (k % per_column) as i32 * row;
        let x0 = 4 + (k / per_column) as i32 * col_w;
        let colour = series_colour(k);
        let line = colour.stroke_width(LINE_PX);
        if series_dashed(k) {
            area.draw(&DashedPathElement::new(
                vec![(x0, y), (x0 + len, y)],
                9,
                5,
                line,
            ))
            .map_err(draw_err)?;
        } else {
            area.draw(&PathElement::new(vec![(x0, y), (x0 + len, y)], line))
                .map_err(draw_err)?;
        }
        if s.markers {
            area.draw(&Circle::new((x0 + len / 2, y), MARKER_PX, colour.filled()))
                .map_err(draw_err)?;
        }
        area.draw(&Text::new(
            s.label.clone(),
            (x0 + len + 10, y),
            style.pos(Pos::new(HPos::Left, VPos::Center)),
        ))
        .map_err(draw_err)?;
    }
    Ok(())
}

/// Where a legend box goes inside the plotting area: its top-left corner,
/// how many curve points it covers there, its size in pixels.
struct LegendSpot {
    covered: usize,
    at: (i32, i32),
    size: (i32, i32),
}

/// Top-left corner (pixels within the plotting area) of the legend box: the
/// first of the corners (upper right, upper left, lower right, lower left)
/// and edge middles that covers the fewest points sampled along the curves;
/// with the number of points it covers there and the box's size.
fn legend_position<DB: DrawingBackend>(
    chart: &Chart<'_, DB>,
    xa: &Axis,
    ya: &Axis,
    data: &LineData,
) -> Result<LegendSpot, String> {
    let area = chart.plotting_area().strip_coord_spec();
    let (pw, ph) = area.dim_in_pixel();
    let (pw, ph) = (pw as f64, ph as f64);
    let style = text(LEGEND_PX);
    let mut lines = MultiLineText::<_, &str>::new((0, 0), &style);
    for s in &data.series {
        lines.push_line(s.label.as_str());
    }
    let (w, h) = lines.estimate_dimension().map_err(draw_err)?;
    let w = w + (LEGEND_SAMPLE_PX + 2 * LEGEND_MARGIN_PX) as i32;
    let h = h + 2 * LEGEND_MARGIN_PX as i32;

    let to_px = |(x, y): (f64, f64)| ((x - xa.lo) / xa.span() * pw, (ya.hi - y) / ya.span() * ph);
    let mut samples = Vec::new();
    for s in &data.series {
        for run in &s.runs {
            let mut prev: Option<(f64, f64)> = None;
            for &q in run {
                let b = to_px(q);
                if let Some(a) = prev {
                    let n = ((b.0 - a.0).hypot(b.1 - a.1) / 4.0)
                        .ceil()
                        .clamp(1.0, 2000.0) as usize;
                    for i in 1..n {
                        let f = i as f64 / n as f64;
                        samples.push((a.0 + f * (b.0 - a.0), a.1 + f * (b.1 - a.1)));
                    }
                }
                samples.push(b);
                prev = Some(b);
            }
        }
    }
    let inset = 10;
    let (aw, ah) = (pw as i32, ph as i32);
    let (left, right) = (inset, aw - w - inset);
    let (top, bottom) = (inset, ah - h - inset);
    let (mid_x, mid_y) = ((aw - w) / 2, (ah - h) / 2);
    let candidates = [
        (right, top),
        (left, top),
        (right, bottom),
        (left, bottom),
        (right, mid_y),
        (left, mid_y),
        (mid_x, top),
        (mid_x, bottom),
    ];
    let pad = 6.0;
    let best = candidates
        .iter()
        .map(|&(x, y)| {
            let (x0, y0) = (x as f64 - pad, y as f64 - pad);
            let (x1, y1) = ((x + w) as f64 + pad, (y + h) as f64 + pad);
            let covered = samples
                .iter()
                .filter(|s| s.0 >= x0 && s.0 <= x1 && s.1 >= y0 && s.1 <= y1)
                .count();
            (covered, (x, y))
        })
        .min_by_key(|c| c.0)
        .unwrap_or((0, (left, top)));
    Ok(LegendSpot {
        covered: best.0,
        at: best.1,
        size: (w, h),
    })
}

// ---------------------------------------------------------------------------
// Heatmaps

struct HeatData {
    x_edges: Vec<f64>,
    y_edges: Vec<f64>,
    x: Axis,
    y: Axis,
    /// Colour scale in plot coordinates (log10 of z if `log_z`).
    z: Axis,
    /// Cells without a value (None, NaN, ±inf).
    missing: usize,
    /// Cells with a value ≤ 0 on a log colour scale.
    nonpositive: usize,
    empty_note: Option<String>,
}

/// Edges of the cells centred on `c`: midpoints between neighbours, and the
/// outer cells as wide beyond their centre as towards their neighbour.
fn cell_edges(c: &[f64]) -> Vec<f64> {
    match c.len() {
        0 => Vec::new(),
        1 => {
            let half = if c[0] != 0.0 { 0.1 * c[0].abs() } else { 0.5 };
            vec![c[0] - half, c[0] + half]
        }
        n => {
            let mut e = Vec::with_capacity(n + 1);
            e.push(c[0] - 0.5 * (c[1] - c[0]));
            for i in 1..n {
                e.push(0.5 * (c[i - 1] + c[i]));
            }
            e.push(c[n - 1] + 0.5 * (c[n - 1] - c[n - 2]));
            e
        }
    }
}

fn check_grid(name: &str, c: &[f64]) -> Result<(), String> {
    if let Some(i) = c.iter().position(|v| !v.is_finite()) {
        return Err(format!("heatmap grid {name}[{i}] = {} is not finite", c[i]));
    }
    let up = c.windows(2).all(|w| w[0] < w[1]);
    let down = c.windows(2).all(|w| w[0] > w[1]);
    if !(up || down) {
        return Err(format!(
            "heatmap grid {name} is not strictly increasing or decreasing"
        ));
    }
    Ok(())
}

impl HeatData {
    fn new(h: &Heatmap) -> Result<HeatData, String> {
        check_grid("x", &h.x)?;
        check_grid("y", &h.y)?;
        if h.z.len() != h.y.len() {
            return Err(format!(
                "heatmap z has {} rows but y has {} values",
                h.z.len(),
                h.y.len()
            ));
        }
        if let Some((j, row)) = h.z.iter().enumerate().find(|(_, r)| r.len() != h.x.len()) {
            return Err(format!(
                "heatmap z row {j} has {} values but x has {}",
                row.len(),
                h.x.len()
            ));
        }
        let (x_edges, y_edges) = (cell_edges(&h.x), cell_edges(&h.y));
        let edge_axis = |e: &[f64]| Axis::fit(e.iter().copied(), false, 0.0);
        let (x, y) = if finite_edges(&x_edges) && finite_edges(&y_edges) {
            (edge_axis(&x_edges), edge_axis(&y_edges))
        } else {
            (Axis::fit([], false, 0.0), Axis::fit([], false, 0.0))
        };
        let mut missing = 0;
        let mut nonpositive = 0;
        let mut values = Vec::new();
        for v in h.z.iter().flatten() {
            match v.filter(|v| v.is_finite()) {
                None => missing += 1,
                Some(v) => match to_plot(v, h.log_z) {
                    Some(p) => values.push(p),
                    None => nonpositive += 1,
                },
            }
        }
        let z = Axis::fit(values.iter().copied(), h.log_z, 0.0);
        let empty_note = if h.x.is_empty() || h.y.is_empty() {
            Some("nothing to draw: empty grid".to_string())
        } else if values.is_empty() && h.log_z {
            Some("nothing to draw: no finite positive values for the log scale".to_string())
        } else if values.is_empty() {
            Some("nothing to draw: no finite values".to_string())
        } else {
            None
        };
        Ok(HeatData {
            x_edges,
            y_edges,
            x,
            y,
            z,
            missing,
            nonpositive,
            empty_note,
        })
    }

    /// The fill of a cell with value `v`, or `None` for a grey cell.
    fn colour(&self, v: Option<f64>, log: bool) -> Option<RGBColor> {
        let p = to_plot(v?, log)?;
        Some(viridis((p - self.z.lo) / self.z.span()))
    }
}

/// Edges that are all finite, so that they can bound an axis.
fn finite_edges(e: &[f64]) -> bool {
    !e.is_empty() && e.iter().all(|v| v.is_finite())
}

fn draw_heatmap<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    h: &Heatmap,
    data: &HeatData,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(draw_err)?;
    let area = root
        .margin(8, 8, 8, 8)
        .titled(&h.title, title_text())
        .map_err(draw_err)?;
    let (aw, _) = area.dim_in_pixel();
    let layout = BarLayout::new(&area, data)?;
    let (main, bar) = area.split_horizontally(aw.saturating_sub(layout.panel));
    let areas = label_areas(&main, &data.x, &data.y)?;
    let mut chart = build_chart(&main, &data.x, &data.y, areas, 30)?;

    {
        let plot = chart.plotting_area();
        for (j, row) in h.z.iter().enumerate() {
            for (i, &v) in row.iter().enumerate() {
                let (x0, x1) = (data.x_edges[i], data.x_edges[i + 1]);
                let (y0, y1) = (data.y_edges[j], data.y_edges[j + 1]);
                match data.colour(v, h.log_z) {
                    Some(c) => plot
                        .draw(&Rectangle::new([(x0, y0), (x1, y1)], c.filled()))
                        .map_err(draw_err)?,
                    None => {
                        plot.draw(&Rectangle::new([(x0, y0), (x1, y1)], MISSING_FILL.filled()))
                            .map_err(draw_err)?;
                        let cross = MISSING_CROSS.stroke_width(2);
                        plot.draw(&PathElement::new(vec![(x0, y0), (x1, y1)], cross))
                            .map_err(draw_err)?;
                        plot.draw(&PathElement::new(vec![(x0, y1), (x1, y0)], cross))
                            .map_err(draw_err)?;
                    }
                }
            }
        }
    }
    draw_axes(&mut chart, &data.x, &data.y, &h.x_label, &h.y_label, false)?;
    if let Some(note) = &data.empty_note {
        draw_note(&chart.plotting_area().strip_coord_spec(), note)?;
    }
    draw_colour_bar(&bar, h, data, &layout, areas.0)?;
    root.present().map_err(draw_err)
}

/// Layout of the colour-bar panel: its width, the width of the tick-label
/// area right of the bar, and the lines explaining grey cells.
struct BarLayout {
    panel: u32,
    right_area: u32,
    notes: Vec<String>,
    notes_width: u32,
}

impl BarLayout {
    fn new<DB: DrawingBackend>(
        area: &DrawingArea<DB, Shift>,
        data: &HeatData,
    ) -> Result<BarLayout, String> {
        let tick_w = max_label_width(area, &data.z.ticks().labels)?;
        let right_area = 2 * TICK_MARK_PX as u32 + tick_w + 14 + LABEL_PX as u32 + 8;
        let grey = data.missing + data.nonpositive;
        let mut notes = Vec::new();
        if grey > 0 {
            let cells = if grey == 1 { "cell" } else { "cells" };
            notes.push(format!("no value: {grey} {cells}"));
        }
        if data.nonpositive > 0 {
            notes.push(format!("({} of them ≤ 0)", data.nonpositive));
        }
        let notes_width = if notes.is_empty() {
            0
        } else {
            SWATCH_PX + 10 + max_label_width(area, &notes)?
        };
        let panel = (30 + COLOUR_BAR_PX + right_area + 8).max(notes_width + 16);
        Ok(BarLayout {
            panel,
            right_area,
            notes,
            notes_width,
        })
    }
}

/// The colour bar, with ticks and the z label on its right, and below it
/// the grey swatch for cells without a drawable value (if there are any).
/// `bottom` is the height of the heatmap's x label area, so that the bar
/// spans the same height as the cells.
fn draw_colour_bar<DB: DrawingBackend>(
    bar: &DrawingArea<DB, Shift>,
    h: &Heatmap,
    data: &HeatData,
    layout: &BarLayout,
    bottom: u32,
) -> Result<(), String> {
    let ticks = data.z.ticks();
    let unit = Axis {
        log: false,
        lo: 0.0,
        hi: 1.0,
    };
    let bar_left = layout
        .panel
        .saturating_sub(8 + layout.right_area + COLOUR_BAR_PX);
    let mut chart = ChartBuilder::on(bar)
        .margin_top(12)
        .margin_bottom(8 + bottom)
        .margin_left(bar_left)
        .margin_right(8)
        .right_y_label_area_size(layout.right_area)
        .build_cartesian_2d(unit.coord(), data.z.coord())
        .map_err(draw_err)?;
    let strips = 256;
    for k in 0..strips {
        let f0 = k as f64 / strips as f64;
        let f1 = (k + 1) as f64 / strips as f64;
        let z0 = data.z.lo + f0 * data.z.span();
        // Overlap the next strip slightly so that no seam shows.
        let z1 = data.z.lo + (f1 + 0.5 / strips as f64).min(1.0) * data.z.span();
        let c = viridis(0.5 * (f0 + f1));
        chart
            .plotting_area()
            .draw(&Rectangle::new([(0.0, z0), (1.0, z1)], c.filled()))
            .map_err(draw_err)?;
    }
    let fz = |v: &f64| tick_label(&ticks, *v);
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_label_formatter(&fz)
        .y_desc(h.z_label.as_str())
        .axis_desc_style(text(LABEL_PX))
        .label_style(text(TICK_PX))
        .axis_style(BLACK.stroke_width(2))
        .set_all_tick_mark_size(TICK_MARK_PX)
        .draw()
        .map_err(draw_err)?;
    chart
        .plotting_area()
        .draw(&Rectangle::new(
            [(unit.lo, data.z.hi), (unit.hi, data.z.lo)],
            BLACK.stroke_width(1),
        ))
        .map_err(draw_err)?;

    if !layout.notes.is_empty() {
        let (_, bh) = bar.dim_in_pixel();
        let s = SWATCH_PX as i32;
        let y = bh as i32 - bottom as i32 + 16;
        let x0 = (bar_left as i32).min(layout.panel as i32 - 8 - layout.notes_width as i32);
        bar.draw(&Rectangle::new(
            [(x0, y), (x0 + s, y + s)],
            MISSING_FILL.filled(),
        ))
        .map_err(draw_err)?;
        let cross = MISSING_CROSS.stroke_width(2);
        bar.draw(&PathElement::new(vec![(x0, y), (x0 + s, y + s)], cross))
            .map_err(draw_err)?;
        bar.draw(&PathElement::new(vec![(x0, y + s), (x0 + s, y)], cross))
            .map_err(draw_err)?;
        let style = text(TICK_PX).pos(Pos::new(HPos::Left, VPos::Center));
        for (k, line) in layout.notes.iter().enumerate() {
            let ly = y + s / 2 + k as i32 * (TICK_PX as i32 + 6);
            bar.draw_text(line, &style, (x0 + s + 10, ly))
                .map_err(draw_err)?;
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------
// Files

/// `<stem><ext>`, appending rather than replacing an extension.
fn with_suffix(stem: &Path, ext: &str) -> PathBuf {
    let mut s: OsString = stem.as_os_str().to_owned();
    s.push(ext);
    PathBuf::from(s)
}

// ---------------------------------------------------------------------------
// Status grids

/// How a cell of a [`StatusGrid`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellStatus {
    /// Ran to the end.
    Completed,
    /// Stopped where the formulation stops by design (a singular set).
    Stopped,
    /// Failed (integrator error, budget, set-up error).
    Failed,
    /// Not run.
    Missing,
}

/// One cell: its status and a short text drawn in it (a number, a time).
#[derive(Debug, Clone, PartialEq)]
pub struct Cell {
    pub status: CellStatus,
    pub text: String,
}

/// A table drawn as a figure: rows (cases) × columns (methods), each cell
/// coloured by how the run ended, with a short text; the stability map of a
/// catalogue of cases.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct StatusGrid {
    pub title: String,
    /// Row names, top to bottom.
    pub rows: Vec<String>,
    /// Column names, left to right (drawn vertically above the columns).
    pub columns: Vec<String>,
    /// `cells[row][column]`.
    pub cells: Vec<Vec<Cell>>,
    /// A line under the grid saying what the numbers are.
    pub note: String,
}

const STATUS_FILL: [(CellStatus, RGBColor, &str); 4] = [
    (CellStatus::Completed, RGBColor(198, 232, 190), "completed"),
    (
        CellStatus::Stopped,
        RGBColor(253, 222, 160),
        "stopped at a singular set",
    ),
    (CellStatus::Failed, RGBColor(242, 170, 170), "failed"),
    (CellStatus::Missing, RGBColor(225, 225, 225), "not run"),
];

/// Draws `g` and writes `<stem>.png` and `<stem>.svg` (PNG first). The figure
/// is 1200 px wide and as tall as the rows need.
pub fn status_grid(g: &StatusGrid, stem: &Path) -> Result<Vec<PathBuf>, String> {
    if g.cells.len() != g.rows.len() || g.cells.iter().any(|r| r.len() != g.columns.len()) {
        return Err(format!(
            "status grid `{}`: {} rows × {} columns but cells are {}",
            g.title,
            g.rows.len(),
            g.columns.len(),
            g.cells
                .iter()
                .map(|r| r.len().to_string())
                .collect::<Vec<_>>()
                .join("/")
        ));
    }
    let size = (SIZE.0, grid_height(g));
    write_outputs_sized(
        stem,
        size,
        |root| draw_status_grid(&root, g),
        |root| draw_status_grid(&root, g),
    )
}

const GRID_ROW_PX: u32 = 52;

/// Height of the column headers: the longest name (drawn vertically),
/// estimated at 0.6 em per character.
fn grid_header_px(g: &StatusGrid) -> u32 {
    let chars = g
        .columns
        .iter()
        .map(|c| c.chars().count())
        .max()
        .unwrap_or(0);
    (chars as f64 * 0.6 * LEGEND_PX) as u32 + 24
}

/// The note under the key, one line per `; `-separated part.
fn grid_note_lines(g: &StatusGrid) -> Vec<&str> {
    g.note.split("; ").filter(|l| !l.is_empty()).collect()
}

fn grid_height(g: &StatusGrid) -> u32 {
    90 + grid_header_px(g)
        + GRID_ROW_PX * g.rows.len().max(1) as u32
        + 80
        + 34 * grid_note_lines(g).len() as u32
}

fn draw_status_grid<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    g: &StatusGrid,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(draw_err)?;
    let area = root
        .margin(8, 8, 8, 8)
        .titled(&g.title, title_text())
        .map_err(draw_err)?;
    let (aw, _) = area.dim_in_pixel();
    let label = text(LEGEND_PX);
    let small = text(TICK_PX);
    let row_w = max_label_width(&area, &g.rows)? + 24;
    let cols = g.columns.len().max(1) as i32;
    let col_w = ((aw as i32 - row_w as i32 - 16) / cols).max(20);
    let (x0, y0) = (row_w as i32, grid_header_px(g) as i32);
    let row_h = GRID_ROW_PX as i32;
    // Column names, vertical, bottom-aligned on the grid.
    for (c, name) in g.columns.iter().enumerate() {
        let x = x0 + c as i32 * col_w + col_w / 2;
        let style = label
            .transform(FontTransform::Rotate270)
            .pos(Pos::new(HPos::Left, VPos::Center));
        area.draw(&Text::new(name.clone(), (x, y0 - 10), style))
            .map_err(draw_err)?;
    }
    for (r, name) in g.rows.iter().enumerate() {
        let y = y0 + r as i32 * row_h;
        area.draw(&Text::new(
            name.clone(),
            (x0 - 12, y + row_h / 2),
            label.pos(Pos::new(HPos::Right, VPos::Center)),
        ))
        .map_err(draw_err)?;
        for (c, cell) in g.cells[r].iter().enumerate() {
            let x = x0 + c as i32 * col_w;
            let fill = STATUS_FILL
                .iter()
                .find(|f| f.0 == cell.status)
                .map(|f| f.1)
                .unwrap_or(WHITE);
            area.draw(&Rectangle::new(
                [(x, y), (x + col_w, y + row_h)],
                fill.filled(),
            ))
            .map_err(draw_err)?;
            area.draw(&Rectangle::new(
                [(x, y), (x + col_w, y + row_h)],
                BLACK.mix(0.35).stroke_width(1),
            ))
            .map_err(draw_err)?;
            area.draw(&Text::new(
                cell.text.clone(),
                (x + col_w / 2, y + row_h / 2),
                small.pos(Pos::new(HPos::Center, VPos::Center)),
            ))
            .map_err(draw_err)?;
        }
    }
    // Key and note under the grid.
    let ky = y0 + g.rows.len() as i32 * row_h + 24;
    let mut kx = x0;
    for (_, colour, what) in STATUS_FILL {
        area.draw(&Rectangle::new(
            [(kx, ky), (kx + SWATCH_PX as i32, ky + SWATCH_PX as i32)],
            colour.filled(),
        ))
        .map_err(draw_err)?;
        area.draw(&Rectangle::new(
            [(kx, ky), (kx + SWATCH_PX as i32, ky + SWATCH_PX as i32)],
            BLACK.mix(0.35),
        ))
        .map_err(draw_err)?;
        let tx = kx + SWATCH_PX as i32 + 8;
        area.draw(&Text::new(
            what,
            (tx, ky + SWATCH_PX as i32 / 2),
            small.pos(Pos::new(HPos::Left, VPos::Center)),
        ))
        .map_err(draw_err)?;
        let (w, _) = area.estimate_text_size(what, &small).map_err(draw_err)?;
        kx = tx + w as i32 + 28;
    }
    for (i, line) in grid_note_lines(g).into_iter().enumerate() {
        area.draw(&Text::new(
            line.to_string(),
            (x0, ky + SWATCH_PX as i32 + 30 + 34 * i as i32),
            small.pos(Pos::new(HPos::Left, VPos::Center)),
        ))
        .map_err(draw_err)?;
    }
    root.present().map_err(draw_err)
}

/// Renders the PNG and the SVG of one figure and writes both atomically.
fn write_outputs(
    stem: &Path,
    png: impl FnOnce(DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), String>,
    svg: impl FnOnce(DrawingArea<SVGBackend<'_>, Shift>) -> Result<(), String>,
) -> Result<Vec<PathBuf>, String> {
    write_outputs_sized(stem, SIZE, png, svg)
}

/// [`write_outputs`] for a figure of `size` pixels.
fn write_outputs_sized(
    stem: &Path,
    size: (u32, u32),
    png: impl FnOnce(DrawingArea<BitMapBackend<'_>, Shift>) -> Result<(), String>,
    svg: impl FnOnce(DrawingArea<SVGBackend<'_>, Shift>) -> Result<(), String>,
) -> Result<Vec<PathBuf>, String> {
    ensure_font()?;
    if stem.file_name().is_none() {
        return Err(format!("plot path {} has no file name", stem.display()));
    }
    if let Some(dir) = stem.parent().filter(|d| !d.as_os_str().is_empty()) {
        fs::create_dir_all(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    let (png_path, svg_path) = (with_suffix(stem, ".png"), with_suffix(stem, ".svg"));

    // Rendered into memory and encoded here: the best deflate level with
    // adaptive filters makes the committed figures 2–3 times smaller than
    // plotters' own encoder.
    let mut pixels = vec![0u8; (size.0 * size.1 * 3) as usize];
    png(BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area())?;
    let mut bytes = Vec::new();
    {
        let mut enc = ::png::Encoder::new(&mut bytes, size.0, size.1);
        enc.set_color(::png::ColorType::Rgb);
        enc.set_depth(::png::BitDepth::Eight);
        enc.set_compression(::png::Compression::Best);
        enc.set_adaptive_filter(::png::AdaptiveFilterType::Adaptive);
        let mut w = enc
            .write_header()
            .map_err(|e| format!("cannot encode {}: {e}", png_path.display()))?;
        w.write_image_data(&pixels)
            .map_err(|e| format!("cannot encode {}: {e}", png_path.display()))?;
    }
    let write = |path: &Path, bytes: &[u8]| {
        crate::record::write_atomic(path, bytes)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))
    };
    write(&png_path, &bytes)?;
    let mut doc = String::new();
    svg(SVGBackend::with_string(&mut doc, size).into_drawing_area())?;
    write(&svg_path, doc.as_bytes())?;
    Ok(vec![png_path, svg_path])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sci_labels_are_short() {
        assert_eq!(fmt_sci(1e-6, 3), "1e-6");
        assert_eq!(fmt_sci(2.5e3, 3), "2.5e3");
        assert_eq!(fmt_sci(10f64.powf(-2.0f64 + 2f64.log10()), 3), "2e-2");
        assert_eq!(fmt_sci(-0.00125, 3), "-1.25e-3");
    }

    #[test]
    fn linear_ticks_are_round() {
        let (t, step) = linear_ticks(-0.07, 1.03, 8.0);
        assert_eq!(step, 0.2);
        let labels: Vec<_> = t.iter().map(|&v| fmt_linear(v, step, false)).collect();
        assert_eq!(labels, ["0.0", "0.2", "0.4", "0.6", "0.8", "1.0"]);
    }

    #[test]
    fn log_ticks_cover_narrow_and_wide_ranges() {
        let wide = log_ticks(-12.3, 0.2);
        assert!(
            wide.bold.len() >= 4 && wide.bold.len() <= 9,
            "{:?}",
            wide.labels
        );
        assert!(
            wide.labels.contains(&"1e-6".to_string()),
            "{:?}",
            wide.labels
        );
        let narrow = log_ticks(2.0f64.log10() - 3.0, 8.0f64.log10() - 3.0);
        assert!(narrow.bold.len() >= 3, "{:?}", narrow.labels);
        let tiny = log_ticks(1.001f64.log10(), 1.004f64.log10());
        assert!(tiny.bold.len() >= 2, "{:?}", tiny.labels);
        let distinct: std::collections::BTreeSet<_> = tiny.labels.iter().collect();
        assert_eq!(distinct.len(), tiny.labels.len(), "{:?}", tiny.labels);
    }

    #[test]
    fn edges_of_non_uniform_grid() {
        assert_eq!(cell_edges(&[0.0, 1.0, 3.0]), vec![-0.5, 0.5, 2.0, 4.0]);
        assert_eq!(cell_edges(&[2.0]), vec![1.8, 2.2]);
    }

    #[test]
    fn viridis_ends() {
        assert_eq!(viridis(0.0), RGBColor(0x44, 0x01, 0x54));
        assert_eq!(viridis(1.0), RGBColor(0xfd, 0xe7, 0x25));
        assert_eq!(viridis(f64::NAN), viridis(0.0));
    }
}
