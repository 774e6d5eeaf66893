//! Line plots: curves on shared (linear or logarithmic) axes, with a
//! legend placed where it covers no curve.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::element::{DashedPathElement, MultiLineText};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::{Axis, Chart, build_chart, draw_axes, draw_note, label_areas, to_plot};
use super::style::{
    LEGEND_MARGIN_PX, LEGEND_PX, LEGEND_SAMPLE_PX, LINE_PX, MARKER_MAX_POINTS, MARKER_PX, Pen,
    SIZE, TICK_PX, draw_err, text, titled,
};
use super::write_outputs;

/// One curve of a [`LinePlot`]: the points `(x[i], y[i])` joined in order.
///
/// Points that cannot be drawn (NaN, ±inf, or non-positive on a log axis)
/// break the curve into separate pieces; the legend then says how many
/// points were left out. Series with at most 40 points, and isolated points
/// between gaps, are also drawn as dots. A named series that a later one of
/// another colour coincides with (two formulations that take the same steps
/// to the same errors) gets a band beneath it, and its legend entry says so
/// (`mark_covered` has the rule).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Series {
    /// Legend text; a series with an empty label has no legend entry
    /// (further branches of a family already named once).
    pub label: String,
    /// Abscissae, same length as `y`.
    pub x: Vec<f64>,
    /// Ordinates, same length as `x`.
    pub y: Vec<f64>,
    /// Colour and dash (default: by the series' position in the plot).
    pub pen: Option<Pen>,
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
    /// A fixed range of the vertical axis (data values, low then high):
    /// curves leaving it are cut where they cross its edges. Default: fitted
    /// to the data.
    pub y_range: Option<[f64; 2]>,
    /// The curves, drawn in order; each in its [`Series::pen`], or else in
    /// the Okabe–Ito palette by position (from the eighth series on the
    /// colours repeat with dashed lines).
    pub series: Vec<Series>,
    /// Vertical lines at given abscissae across the whole vertical axis
    /// (which is fitted to the series alone), after the series.
    pub verticals: Vec<Vertical>,
}

/// A vertical line of a [`LinePlot`] with its legend text.
#[derive(Debug, Clone, PartialEq)]
pub struct Vertical {
    pub label: String,
    pub x: f64,
    pub pen: Pen,
}

/// Draws `p` and writes `<stem>.png` and `<stem>.svg`; returns both paths
/// (PNG first).
///
/// The extensions are appended to `stem` (a stem `out/h=0.1` gives
/// `out/h=0.1.png`). Empty or undrawable data gives a frame with a note, not
/// an error; see the module documentation.
pub fn line_plot(p: &LinePlot, stem: &Path) -> Result<Vec<PathBuf>, String> {
    super::check_units(&[&p.x_label, &p.y_label])?;
    let data = LineData::new(p)?;
    write_outputs(
        stem,
        SIZE,
        |root| draw_line_plot(&root, p, &data, Joins::Segments),
        |root| draw_line_plot(&root, p, &data, Joins::Polyline),
    )
}

struct SeriesData {
    /// Legend text, with a note on points left out.
    label: String,
    pen: Pen,
    /// Maximal runs of drawable points, in plot coordinates (see [`Axis`]).
    runs: Vec<Vec<(f64, f64)>>,
    markers: bool,
    /// The height of the stack of later series that coincide with this one
    /// ([`mark_covered`]): it is drawn with a band beneath it,
    /// [`COVERED_EXTRA_PX`] wider per level, so that all of them show.
    covered: u32,
}

/// The band beneath a covered series is its colour mixed with white in this
/// proportion: lighter than the line, so that the line over it stays
/// readable.
const BAND_SHADE: f64 = 0.45;

/// How much wider than [`LINE_PX`] (and its dots' radius) a covered series
/// is drawn: its colour shows as a band on both sides of the line above.
const COVERED_EXTRA_PX: u32 = 6;

/// A point of one series covers a point of another within this fraction of
/// each axis' span (about 4 pixels on the plot).
const COVER_FRACTION: f64 = 0.004;

impl SeriesData {
    /// The band drawn beneath a covered series (solid, its colour made
    /// lighter); nothing for one that no other covers.
    /// Width of the band (0: none).
    fn band_px(&self) -> u32 {
        if self.covered > 0 {
            LINE_PX + COVERED_EXTRA_PX * self.covered
        } else {
            0
        }
    }

    fn band(&self) -> ShapeStyle {
        if self.covered > 0 {
            // Mixed with white, opaque: overlapping pieces of the band
            // (segments and the discs at their joins) do not darken.
            let RGBColor(r, g, b) = self.pen.rgb();
            let light = |c: u8| (c as f64 * BAND_SHADE + 255.0 * (1.0 - BAND_SHADE)).round() as u8;
            RGBColor(light(r), light(g), light(b)).stroke_width(self.band_px())
        } else {
            TRANSPARENT.stroke_width(0)
        }
    }

    fn marker(&self) -> (i32, ShapeStyle) {
        let (r, style) = marker(self.pen);
        (r + (COVERED_EXTRA_PX * self.covered) as i32 / 2, style)
    }
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
            if let Some(range) = p.y_range {
                let lo = to_plot(range[0], p.log_y).unwrap_or(f64::NEG_INFINITY);
                let hi = to_plot(range[1], p.log_y).unwrap_or(f64::INFINITY);
                runs = runs.iter().flat_map(|r| clip_run(r, lo, hi)).collect();
            }
            let drawn: usize = if p.y_range.is_some() {
                s.x.len()
            } else {
                runs.iter().map(Vec::len).sum()
            };
            let label = if drawn == s.x.len() || s.label.is_empty() {
                s.label.clone()
            } else {
                format!("{} ({})", s.label, hidden_note(s, p, drawn))
            };
            series.push(SeriesData {
                label,
                pen: s.pen.unwrap_or_else(|| Pen::by_position(series.len())),
                runs,
                markers: s.x.len() <= MARKER_MAX_POINTS,
                covered: 0,
            });
        }
        let points = || series.iter().flat_map(|s| s.runs.iter().flatten());
        let verticals: Vec<(&Vertical, f64)> = p
            .verticals
            .iter()
            .filter_map(|v| Some((v, to_plot(v.x, p.log_x)?)))
            .collect();
        let x = Axis::fit(
            points().map(|p| p.0).chain(verticals.iter().map(|v| v.1)),
            p.log_x,
            0.03,
        );
        let y = match p.y_range {
            Some([lo, hi]) if lo < hi => Axis {
                log: p.log_y,
                lo: to_plot(lo, p.log_y).unwrap_or(lo),
                hi: to_plot(hi, p.log_y).unwrap_or(hi),
            },
            _ => Axis::fit(points().map(|p| p.1), p.log_y, 0.05),
        };
        let empty_note = if points().next().is_some() {
            None
        } else if series.is_empty() {
            Some("nothing to draw: no series".to_string())
        } else if p.log_x || p.log_y {
            Some("nothing to draw: no finite positive values for the log axis".to_string())
        } else {
            Some("nothing to draw: no finite values".to_string())
        };
        for (v, px) in verticals {
            series.push(SeriesData {
                label: v.label.clone(),
                pen: v.pen,
                runs: vec![vec![(px, y.lo), (px, y.hi)]],
                markers: false,
                covered: 0,
            });
        }
        mark_covered(&mut series, &x, &y);
        Ok(LineData {
            series,
            x,
            y,
            empty_note,
        })
    }
}

/// The points of one series on a grid of cells [`COVER_FRACTION`] of each
/// axis' span wide, for the search of coinciding series in time linear in
/// their points.
struct Cells {
    points: Vec<(f64, f64)>,
    grid: HashMap<(i64, i64), Vec<(f64, f64)>>,
}

impl Cells {
    fn new(s: &SeriesData, cell: (f64, f64)) -> Cells {
        let points: Vec<(f64, f64)> = s.runs.iter().flatten().copied().collect();
        let mut grid: HashMap<(i64, i64), Vec<(f64, f64)>> = HashMap::new();
        for &p in &points {
            grid.entry(Cells::key(p, cell)).or_default().push(p);
        }
        Cells { points, grid }
    }

    fn key(p: (f64, f64), cell: (f64, f64)) -> (i64, i64) {
        ((p.0 / cell.0).floor() as i64, (p.1 / cell.1).floor() as i64)
    }

    /// Whether every point of `self` is within one cell of a point of
    /// `other` in both coordinates.
    fn within(&self, other: &Cells, cell: (f64, f64)) -> bool {
        let near = |a: (f64, f64), b: (f64, f64)| {
            (a.0 - b.0).abs() <= cell.0 && (a.1 - b.1).abs() <= cell.1
        };
        self.points.iter().all(|&a| {
            let (kx, ky) = Cells::key(a, cell);
            (-1..=1).any(|dx| {
                (-1..=1).any(|dy| {
                    other
                        .grid
                        .get(&(kx + dx, ky + dy))
                        .is_some_and(|ps| ps.iter().any(|&b| near(a, b)))
                })
            })
        })
    }

    /// Each series within the other: a line through the points of another
    /// series (the common end of many curves) does not hide it.
    /// (`within` stops at the first point without a neighbour, so series
    /// that part cost little.)
    fn coincide(&self, other: &Cells, cell: (f64, f64)) -> bool {
        !self.points.is_empty()
            && !other.points.is_empty()
            && self.within(other, cell)
            && other.within(self, cell)
    }
}

/// Bands every named series that later series (drawn over it) coincide
/// with, every point of each near a point of the other ([`Cells`]): one
/// band width more than the widest band among them (a later series of the
/// same colour counts only if it is banded itself: otherwise it looks the
/// same either way), so that each band shows around the ones above it.
/// Its legend entry names the first of them by its label up to a colon, a
/// parenthesis or a comma.
fn mark_covered(series: &mut [SeriesData], x: &Axis, y: &Axis) {
    let cell = (
        COVER_FRACTION * x.span().max(f64::MIN_POSITIVE),
        COVER_FRACTION * y.span().max(f64::MIN_POSITIVE),
    );
    let cells: Vec<Cells> = series.iter().map(|s| Cells::new(s, cell)).collect();
    // From the last series down: a band's width depends on those above it.
    for i in (0..series.len()).rev() {
        // Unnamed series are further branches of a family named once.
        if series[i].label.is_empty() {
            continue;
        }
        let colour = series[i].pen.rgb();
        let mut depth = 0;
        let mut above: Vec<usize> = Vec::new();
        for j in i + 1..series.len() {
            let counts = series[j].pen.rgb() != colour || series[j].covered > 0;
            if counts && cells[i].coincide(&cells[j], cell) {
                depth = depth.max(series[j].covered + 1);
                above.push(j);
            }
        }
        let Some(&first) = above.first() else {
            continue;
        };
        let name = series[first]
            .label
            .split([':', '(', ','])
            .next()
            .unwrap_or("")
            .trim()
            .to_string();
        let name = match (name.is_empty(), above.len()) {
            (true, 1) => "a line lies".to_string(),
            (true, n) => format!("{n} lines lie"),
            (false, 1) => format!("{name} lies"),
            (false, n) => format!("{name} and {} more lie", n - 1),
        };
        let s = &mut series[i];
        s.covered = depth;
        s.label = format!("{} (banded: {name} on it)", s.label);
    }
}

/// The pieces of `run` inside `lo ≤ y ≤ hi` (plot coordinates), each
/// ending at the point where the curve crosses an edge.
fn clip_run(run: &[(f64, f64)], lo: f64, hi: f64) -> Vec<Vec<(f64, f64)>> {
    let inside = |y: f64| (lo..=hi).contains(&y);
    let edge = |a: (f64, f64), b: (f64, f64), y: f64| {
        let f = (y - a.1) / (b.1 - a.1);
        (a.0 + f * (b.0 - a.0), y)
    };
    let mut pieces = Vec::new();
    let mut piece: Vec<(f64, f64)> = Vec::new();
    for (i, &q) in run.iter().enumerate() {
        let prev = (i > 0).then(|| run[i - 1]);
        match (prev, inside(q.1)) {
            (None, true) => piece.push(q),
            (None, false) => {}
            (Some(a), true) => {
                if !inside(a.1) {
                    piece.push(edge(a, q, if a.1 > hi { hi } else { lo }));
                }
                piece.push(q);
            }
            (Some(a), false) => {
                if inside(a.1) {
                    piece.push(edge(a, q, if q.1 > hi { hi } else { lo }));
                    pieces.push(std::mem::take(&mut piece));
                } else if (a.1 > hi) != (q.1 > hi) {
                    // Across the whole range within one segment.
                    let (first, second) = if a.1 > hi { (hi, lo) } else { (lo, hi) };
                    pieces.push(vec![edge(a, q, first), edge(a, q, second)]);
                }
            }
        }
    }
    if !piece.is_empty() {
        pieces.push(piece);
    }
    pieces
}

/// Why points of `s` are not drawn, for its legend entry: zeros or negative
/// values on a log axis (a divergence that is exactly zero at the start),
/// or values that are not finite (a run that stopped).
fn hidden_note(s: &Series, p: &LinePlot, drawn: usize) -> String {
    let (mut zero, mut negative, mut missing) = (0, 0, 0);
    for (&x, &y) in s.x.iter().zip(&s.y) {
        if !x.is_finite() || !y.is_finite() {
            missing += 1;
        } else if (p.log_x && x == 0.0) || (p.log_y && y == 0.0) {
            zero += 1;
        } else if (p.log_x && x < 0.0) || (p.log_y && y < 0.0) {
            negative += 1;
        }
    }
    let count = |n: usize, one: &str, many: &str| match n {
        0 => None,
        1 => Some(format!("1 {one}")),
        n => Some(format!("{n} {many}")),
    };
    let parts: Vec<String> = [
        count(zero, "zero off the log axis", "zeros off the log axis"),
        count(
            negative,
            "negative value off the log axis",
            "negative values off the log axis",
        ),
        count(missing, "value missing", "values missing"),
    ]
    .into_iter()
    .flatten()
    .collect();
    let what = parts.join(", ");
    if drawn == 0 {
        format!("nothing drawable: {what}")
    } else {
        what
    }
}

/// The dots of a series with few points, told apart by the pen's dash as
/// the lines are (two lines of one colour, e.g. one formulation by two
/// integrators, differ in their dots as well): filled for solid, open for
/// dashed, small filled for dotted, large open for long dashes.
fn marker(pen: Pen) -> (i32, ShapeStyle) {
    let colour = pen.rgb();
    match pen.dash {
        super::style::Dash::Solid => (MARKER_PX, colour.filled()),
        super::style::Dash::Dashed => (MARKER_PX + 1, colour.stroke_width(2)),
        super::style::Dash::Dotted => (MARKER_PX - 2, colour.filled()),
        super::style::Dash::LongDash => (MARKER_PX + 3, colour.stroke_width(2)),
    }
}

/// How a solid curve is stroked. The bitmap backend joins the segments of
/// a wide polyline with unbounded miters, so a curve that turns sharply
/// (noise at round-off level on a log axis) throws spikes across the title
/// and the axes; drawn as separate segments it has no joins. SVG viewers
/// bound the miters themselves (miter limit 4), and one polyline keeps the
/// file small.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Joins {
    Segments,
    Polyline,
}

fn draw_line_plot<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    p: &LinePlot,
    data: &LineData,
    joins: Joins,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(draw_err)?;
    let area = titled(&root.margin(8, 8, 8, 8), &p.title)?;
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
    if data.series.iter().any(|s| !s.label.is_empty()) {
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
                let rows = labelled(data).count().div_ceil(columns) as i32;
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

    // Bands first, the widest first, under every line (a band drawn in
    // its series' turn would cover the lines drawn before it).
    let mut banded: Vec<&SeriesData> = data.series.iter().filter(|s| s.covered > 0).collect();
    banded.sort_by_key(|s| std::cmp::Reverse(s.covered));
    for s in banded {
        let band = s.band();
        // Separate segments in a bitmap (no joins: see `Joins`), with a disc
        // at every point for a round join (bare segments leave notches
        // wherever the curve turns).
        let disc = ShapeStyle {
            filled: true,
            ..band
        };
        let r = band.stroke_width.div_ceil(2) as i32;
        for run in s.runs.iter().filter(|r| r.len() >= 2) {
            let run: Vec<(f64, f64)> = run
                .iter()
                .map(|&(x, y)| (xa.value(x), ya.value(y)))
                .collect();
            if joins == Joins::Segments {
                chart
                    .draw_series(
                        run.windows(2)
                            .map(|w| PathElement::new(vec![w[0], w[1]], band)),
                    )
                    .map_err(draw_err)?;
                chart
                    .draw_series(run.iter().map(|&q| Circle::new(q, r, disc)))
                    .map_err(draw_err)?;
            } else {
                // One polyline keeps the file small (a path per segment and
                // a disc per point made the densest SVG five times larger);
                // viewers round off its joins' miters.
                chart
                    .draw_series(LineSeries::new(run.iter().copied(), band))
                    .map_err(draw_err)?;
            }
        }
    }
    for s in &data.series {
        let colour = s.pen.rgb();
        let style = colour.stroke_width(LINE_PX);
        for run in &s.runs {
            let run: Vec<(f64, f64)> = run
                .iter()
                .map(|&(x, y)| (xa.value(x), ya.value(y)))
                .collect();
            if run.len() >= 2 {
                if let Some((dash, gap)) = s.pen.dash.on_plot() {
                    chart
                        .draw_series(DashedLineSeries::new(run.iter().copied(), dash, gap, style))
                        .map_err(draw_err)?;
                } else if joins == Joins::Segments {
                    chart
                        .draw_series(
                            run.windows(2)
                                .map(|w| PathElement::new(vec![w[0], w[1]], style)),
                        )
                        .map_err(draw_err)?;
                } else {
                    chart
                        .draw_series(LineSeries::new(run.iter().copied(), style))
                        .map_err(draw_err)?;
                }
            }
            if s.markers || run.len() == 1 {
                let (r, mark) = s.marker();
                chart
                    .draw_series(run.iter().map(|&q| Circle::new(q, r, mark)))
                    .map_err(draw_err)?;
            }
        }
    }
    // Legend entries, one per named series even if nothing of it could be drawn.
    for s in labelled(data) {
        let colour = s.pen.rgb();
        let style = colour.stroke_width(LINE_PX);
        let band = s.band();
        let (r, mark) = s.marker();
        let r = if s.markers { r } else { 0 };
        let len = LEGEND_SAMPLE_PX as i32 - 14;
        let anno = chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(draw_err)?;
        anno.label(s.label.clone());
        if let Some((dash, gap)) = s.pen.dash.in_legend() {
            anno.legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (len, 0)], band)
                    + DashedPathElement::new(vec![(0, 0), (len, 0)], dash, gap, style)
                    + Circle::new((len / 2, 0), r, mark)
            });
        } else {
            anno.legend(move |(x, y)| {
                EmptyElement::at((x, y))
                    + PathElement::new(vec![(0, 0), (len, 0)], band)
                    + PathElement::new(vec![(0, 0), (len, 0)], style)
                    + Circle::new((len / 2, 0), r, mark)
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

/// The series with a legend entry.
fn labelled(data: &LineData) -> impl Iterator<Item = &SeriesData> {
    data.series.iter().filter(|s| !s.label.is_empty())
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
    let per_column = labelled(data).count().div_ceil(columns.max(1));
    let (aw, _) = area.dim_in_pixel();
    let col_w = aw as i32 / columns.max(1) as i32;
    for (k, s) in labelled(data).enumerate() {
        let y = top + (k % per_column) as i32 * row;
        let x0 = 4 + (k / per_column) as i32 * col_w;
        let colour = s.pen.rgb();
        let line = colour.stroke_width(LINE_PX);
        if s.covered > 0 {
            area.draw(&PathElement::new(vec![(x0, y), (x0 + len, y)], s.band()))
                .map_err(draw_err)?;
        }
        if let Some((dash, gap)) = s.pen.dash.in_legend() {
            area.draw(&DashedPathElement::new(
                vec![(x0, y), (x0 + len, y)],
                dash,
                gap,
                line,
            ))
            .map_err(draw_err)?;
        } else {
            area.draw(&PathElement::new(vec![(x0, y), (x0 + len, y)], line))
                .map_err(draw_err)?;
        }
        if s.markers {
            let (r, mark) = s.marker();
            area.draw(&Circle::new((x0 + len / 2, y), r, mark))
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
    for s in labelled(data) {
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
    // Clear of the curves' lines, and of half the widest band around them.
    let band = data
        .series
        .iter()
        .map(SeriesData::band_px)
        .max()
        .unwrap_or(0);
    let pad = 6.0 + band as f64 / 2.0;
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

#[cfg(test)]
mod tests {
    use super::super::style::{Dash, Pen};
    use super::{LineData, LinePlot, Series, Vertical, clip_run};

    /// A vertical line spans the vertical axis fitted to the series alone
    /// (flat data included), widens the horizontal axis to show itself, and
    /// has its legend entry; it adds no markers.
    #[test]
    fn verticals_span_the_vertical_axis_of_the_series() {
        let pen = Pen {
            colour: 6,
            dash: Dash::Dashed,
        };
        for y in [vec![0.0, 1.0, 3.0], vec![0.0; 3]] {
            let plot = |verticals: Vec<Vertical>| LinePlot {
                x_label: "h [m]".into(),
                y_label: "Im λ [1/s]".into(),
                series: vec![Series {
                    label: "B".into(),
                    x: vec![0.0, 0.5, 1.0],
                    y: y.clone(),
                    pen: None,
                }],
                verticals,
                ..LinePlot::default()
            };
            let without = LineData::new(&plot(Vec::new())).unwrap();
            let mark = Vertical {
                label: "h = l".into(),
                x: 2.0,
                pen,
            };
            let with = LineData::new(&plot(vec![mark])).unwrap();
            assert_eq!((with.y.lo, with.y.hi), (without.y.lo, without.y.hi));
            assert!(without.y.hi > without.y.lo);
            assert!(with.x.hi > 2.0 && without.x.hi < 2.0);
            let v = &with.series[1];
            assert_eq!(v.label, "h = l");
            assert_eq!(v.runs, vec![vec![(2.0, with.y.lo), (2.0, with.y.hi)]]);
            assert!(!v.markers);
        }
    }

    /// A named series that later series of another colour (or banded ones)
    /// coincide with is banded one level above the highest of them, and its
    /// legend names the first by its label up to a colon, a parenthesis or a
    /// comma; series under one of the same colour, unnamed ones, ones that
    /// part anywhere and a point on a longer line are not.
    #[test]
    fn covered_series_are_banded_and_say_by_whom() {
        let line = |label: &str, colour: usize, shift: f64| Series {
            label: label.into(),
            x: vec![1.0, 10.0, 100.0],
            y: vec![1e-3, 1e-6 * (1.0 + shift), 1e-9],
            pen: Some(Pen {
                colour,
                dash: Dash::Solid,
            }),
        };
        let plot = |series: Vec<Series>| LinePlot {
            title: "t".into(),
            x_label: "evaluations [count]".into(),
            y_label: "error [m]".into(),
            log_x: true,
            log_y: true,
            series,
            ..LinePlot::default()
        };
        let d = LineData::new(&plot(vec![
            line("mass: compliance", 4, 0.0),
            line("C: vakonomic (order 8.6)", 2, 1e-4),
            line("B", 0, 0.0),
        ]))
        .unwrap();
        let covered: Vec<u32> = d.series.iter().map(|s| s.covered).collect();
        assert_eq!(covered, [2, 1, 0]);
        assert_eq!(
            d.series[0].label,
            "mass: compliance (banded: C and 1 more lie on it)"
        );
        assert_eq!(
            d.series[1].label,
            "C: vakonomic (order 8.6) (banded: B lies on it)"
        );
        // Parted at one point (a factor 2 at 1e-6 is far on the plot).
        let d = LineData::new(&plot(vec![line("a", 4, 0.0), line("b", 2, 1.0)])).unwrap();
        assert_eq!(d.series[0].covered, 0);
        // A line through a series' only point, and on beyond it, does not
        // hide it.
        let mut end = line("end", 6, 0.0);
        (end.x, end.y) = (vec![10.0, 10.0], vec![1e-6, 1e-6]);
        let d = LineData::new(&plot(vec![end, line("a", 4, 0.0)])).unwrap();
        assert_eq!(d.series[0].covered, 0);
        // A band is one width wider than the widest band above it, and a
        // banded series of the same colour counts.
        let d = LineData::new(&plot(vec![
            line("a", 2, 0.0),
            line("b", 2, 0.0),
            line("c", 0, 0.0),
        ]))
        .unwrap();
        let covered: Vec<u32> = d.series.iter().map(|s| s.covered).collect();
        assert_eq!(covered, [2, 1, 0]);
        // Under a series of the same colour, or unnamed, nothing changes.
        let d = LineData::new(&plot(vec![line("a", 2, 0.0), line("b", 2, 0.0)])).unwrap();
        assert_eq!(d.series[0].covered, 0);
        assert_eq!(d.series[0].label, "a");
        let d = LineData::new(&plot(vec![line("", 4, 0.0), line("c", 0, 0.0)])).unwrap();
        assert_eq!(d.series[0].covered, 0);
        // A named series under an unnamed one is banded, without a name.
        let d = LineData::new(&plot(vec![line("a", 2, 0.0), line("", 4, 0.0)])).unwrap();
        assert_eq!(d.series[0].covered, 1);
        assert_eq!(d.series[0].label, "a (banded: a line lies on it)");
    }

    /// A curve leaving the range is cut where it crosses an edge (by
    /// linear interpolation), and a segment across the whole range keeps
    /// its part between the edges.
    #[test]
    fn runs_are_cut_at_the_edges_of_a_fixed_range() {
        let run = [(0.0, 0.0), (1.0, 2.0), (2.0, 0.5), (3.0, -3.0), (4.0, 3.0)];
        let pieces = clip_run(&run, -1.0, 1.0);
        let want = [
            vec![(0.0, 0.0), (0.5, 1.0)],
            vec![(5.0 / 3.0, 1.0), (2.0, 0.5), (2.0 + 1.5 / 3.5, -1.0)],
            vec![(3.0 + 2.0 / 6.0, -1.0), (3.0 + 4.0 / 6.0, 1.0)],
        ];
        assert_eq!(pieces.len(), want.len());
        for (got, want) in pieces.iter().zip(&want) {
            assert_eq!(got.len(), want.len());
            for (a, b) in got.iter().zip(want) {
                assert!(
                    (a.0 - b.0).abs() < 1e-15 && (a.1 - b.1).abs() < 1e-15,
                    "{a:?} {b:?}"
                );
            }
        }
        assert_eq!(
            clip_run(&[(0.0, 5.0), (1.0, 6.0)], -1.0, 1.0),
            Vec::<Vec<_>>::new()
        );
    }
}
