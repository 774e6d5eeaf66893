//! Axes: ranges, ticks and their labels, and plotters' coordinates
//! (linear, or its logarithmic `LogCoord`) that draw them.

use plotters::coord::Shift;
use plotters::coord::combinators::{IntoLogRange, LogCoord};
use plotters::coord::ranged1d::{DefaultFormatting, KeyPointHint};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::style::{LABEL_PX, NOTE_PX, TICK_MARK_PX, TICK_PX, draw_err, text};

/// An axis range in plot coordinates: the data value itself, or its base-10
/// logarithm on a log axis. Ranges are fitted, widened and ticked in plot
/// coordinates; plotters draws in data values ([`Axis::value`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct Axis {
    pub(super) log: bool,
    pub(super) lo: f64,
    pub(super) hi: f64,
}

/// Tick positions (plot coordinates) with their labels, and positions of
/// the fainter grid lines between them.
pub(super) struct Ticks {
    pub(super) bold: Vec<f64>,
    pub(super) labels: Vec<String>,
    pub(super) light: Vec<f64>,
}

/// How plotters maps data values to pixels along an axis.
enum Scale {
    Linear(RangedCoordf64),
    /// plotters' logarithmic coordinate.
    Log(LogCoord<f64>),
}

/// A plotters coordinate (in data values) with our own tick positions:
/// labelled ticks with grid lines, and fainter grid lines. The ticks are
/// ours because plotters' logarithmic coordinate puts them at powers of ten
/// only, so a range within a decade (an error between 2e-3 and 8e-3) would
/// have none.
pub(super) struct AxisCoord {
    scale: Scale,
    bold: Vec<f64>,
    light: Vec<f64>,
}

impl Ranged for AxisCoord {
    type FormatOption = DefaultFormatting;
    type ValueType = f64;

    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        match &self.scale {
            Scale::Linear(c) => c.map(value, limit),
            Scale::Log(c) => c.map(value, limit),
        }
    }

    fn key_points<Hint: KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        if hint.weight().allow_light_points() {
            self.light.clone()
        } else {
            self.bold.clone()
        }
    }

    fn range(&self) -> std::ops::Range<f64> {
        match &self.scale {
            Scale::Linear(c) => c.range(),
            Scale::Log(c) => c.range(),
        }
    }
}

/// The plot coordinates a log axis may span: its ends must be positive
/// finite doubles (which lie within `10^-323.3 .. 10^308.3`).
const LOG_RANGE: (f64, f64) = (-323.0, 308.0);

/// Maps a data value to plot coordinates; `None` if it cannot be drawn.
pub(super) fn to_plot(v: f64, log: bool) -> Option<f64> {
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
    pub(super) fn fit(values: impl IntoIterator<Item = f64>, log: bool, margin: f64) -> Axis {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values {
            lo = lo.min(v);
            hi = hi.max(v);
        }
        let scale = lo.abs().max(hi.abs());
        if lo > hi {
            (lo, hi) = (0.0, 1.0);
        } else if hi - lo <= 1e-12 * scale || hi == lo {
            let pad = if log {
                0.5
            } else if scale > 0.0 {
                0.1 * scale
            } else {
                1.0
            };
            (lo, hi) = (lo - pad, hi + pad);
        } else {
            let m = margin * (hi - lo);
            if (hi - lo).is_finite() && (lo - m).is_finite() && (hi + m).is_finite() {
                lo -= m;
                hi += m;
            }
        }
        if log {
            // The ends must stay positive finite data values (the margin
            // could take them past the largest or smallest double).
            (lo, hi) = (lo.max(LOG_RANGE.0), hi.min(LOG_RANGE.1));
        }
        Axis { log, lo, hi }
    }

    pub(super) fn span(&self) -> f64 {
        self.hi - self.lo
    }

    /// The data value at plot coordinate `p`.
    pub(super) fn value(&self, p: f64) -> f64 {
        if self.log { 10f64.powf(p) } else { p }
    }

    /// The plot coordinate of data value `v` (not checked for drawability).
    fn plot(&self, v: f64) -> f64 {
        if self.log { v.log10() } else { v }
    }

    /// Widens the range symmetrically to length `span`.
    pub(super) fn widen_to(&mut self, span: f64) {
        if span > self.span() && span.is_finite() {
            let c = 0.5 * (self.lo + self.hi);
            self.lo = c - 0.5 * span;
            self.hi = c + 0.5 * span;
        }
    }

    /// The plotters coordinate of this axis, with our ticks.
    pub(super) fn coord(&self) -> AxisCoord {
        let t = self.ticks();
        let data = |p: &[f64]| p.iter().map(|&p| self.value(p)).collect();
        let (lo, hi) = (self.value(self.lo), self.value(self.hi));
        AxisCoord {
            scale: if self.log {
                Scale::Log((lo..hi).log_scale().into())
            } else {
                Scale::Linear((lo..hi).into())
            },
            bold: data(&t.bold),
            light: data(&t.light),
        }
    }

    /// The label of the bold tick nearest to data value `v`.
    pub(super) fn tick_label(&self, ticks: &Ticks, v: f64) -> String {
        let p = self.plot(v);
        ticks
            .bold
            .iter()
            .zip(&ticks.labels)
            .min_by(|a, b| (a.0 - p).abs().total_cmp(&(b.0 - p).abs()))
            .map(|(_, l)| l.clone())
            .unwrap_or_default()
    }

    pub(super) fn ticks(&self) -> Ticks {
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
pub(super) fn fmt_sci(v: f64, sig: usize) -> String {
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

pub(super) fn max_label_width<DB: DrawingBackend>(
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
pub(super) fn label_areas<DB: DrawingBackend>(
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

pub(super) type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<AxisCoord, AxisCoord>>;

pub(super) fn build_chart<'a, DB: DrawingBackend>(
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
pub(super) fn draw_axes<DB: DrawingBackend>(
    chart: &mut Chart<'_, DB>,
    xa: &Axis,
    ya: &Axis,
    x_label: &str,
    y_label: &str,
    grid: bool,
) -> Result<(), String> {
    let (xt, yt) = (xa.ticks(), ya.ticks());
    let fx = |v: &f64| xa.tick_label(&xt, *v);
    let fy = |v: &f64| ya.tick_label(&yt, *v);
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
            [
                (xa.value(xa.lo), ya.value(ya.hi)),
                (xa.value(xa.hi), ya.value(ya.lo)),
            ],
            BLACK.stroke_width(1),
        ))
        .map_err(draw_err)?;
    Ok(())
}

/// A note in the middle of `area`, on a white box.
pub(super) fn draw_note<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    note: &str,
) -> Result<(), String> {
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

    /// plotters' log coordinate puts a tick's data value where our plot
    /// coordinate says, and a log axis never reaches past the doubles.
    #[test]
    fn log_axes_map_and_stay_finite() {
        let a = Axis::fit([-9.0, -3.0], true, 0.0);
        let c = a.coord();
        assert_eq!(c.map(&1e-9, (0, 600)), 0);
        assert_eq!(c.map(&1e-6, (0, 600)), 300);
        assert_eq!(c.map(&1e-3, (0, 600)), 600);
        assert_eq!(a.tick_label(&a.ticks(), 1.0001e-6), "1e-6");
        let huge = Axis::fit([-300.0, 300.0], true, 0.05);
        assert!(huge.value(huge.lo) > 0.0 && huge.value(huge.hi).is_finite());
    }
}
