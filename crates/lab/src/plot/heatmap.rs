//! Heatmaps: a colour per cell of a (possibly non-uniform) grid, in
//! plotters' viridis colour map, with a colour bar.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::axis::{Axis, build_chart, draw_axes, draw_note, label_areas, max_label_width, to_plot};
use super::style::{
    COLOUR_BAR_PX, LABEL_PX, MISSING_CROSS, MISSING_FILL, SIZE, SWATCH_PX, TICK_MARK_PX, TICK_PX,
    draw_err, text, titled,
};
use super::write_outputs;

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

/// Draws `h` as coloured cells with a colour bar and writes `<stem>.png`
/// and `<stem>.svg`; returns both paths (PNG first).
///
/// The extensions are appended to `stem`. An empty grid or one without a
/// drawable value gives a frame with a note, not an error; see the module
/// documentation.
pub fn heatmap(h: &Heatmap, stem: &Path) -> Result<Vec<PathBuf>, String> {
    super::check_units(&[&h.x_label, &h.y_label, &h.z_label])?;
    let data = HeatData::new(h)?;
    write_outputs(
        stem,
        SIZE,
        |root| draw_heatmap(&root, h, &data),
        |root| draw_heatmap(&root, h, &data),
    )
}

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
        Some(ViridisRGB::get_color_normalized(p, self.z.lo, self.z.hi))
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
    let area = titled(&root.margin(8, 8, 8, 8), &h.title)?;
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
        let z0 = data.z.value(data.z.lo + f0 * data.z.span());
        // Overlap the next strip slightly so that no seam shows.
        let z1 = data
            .z
            .value(data.z.lo + (f1 + 0.5 / strips as f64).min(1.0) * data.z.span());
        let c = ViridisRGB::get_color(0.5 * (f0 + f1));
        chart
            .plotting_area()
            .draw(&Rectangle::new([(0.0, z0), (1.0, z1)], c.filled()))
            .map_err(draw_err)?;
    }
    let fz = |v: &f64| data.z.tick_label(&ticks, *v);
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
            [
                (unit.lo, data.z.value(data.z.hi)),
                (unit.hi, data.z.value(data.z.lo)),
            ],
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edges_of_non_uniform_grid() {
        assert_eq!(cell_edges(&[0.0, 1.0, 3.0]), vec![-0.5, 0.5, 2.0, 4.0]);
        assert_eq!(cell_edges(&[2.0]), vec![1.8, 2.2]);
    }

    /// The colour map runs from viridis' dark purple to its yellow.
    #[test]
    fn viridis_ends() {
        let h = HeatData::new(&Heatmap {
            x: vec![0.0, 1.0],
            y: vec![0.0],
            z: vec![vec![Some(1.0), Some(100.0)]],
            log_z: true,
            ..Heatmap::default()
        })
        .unwrap();
        assert_eq!(h.colour(Some(1.0), true), Some(RGBColor(68, 1, 84)));
        assert_eq!(h.colour(Some(100.0), true), Some(RGBColor(254, 232, 37)));
        assert_eq!(h.colour(Some(0.0), true), None);
        assert_eq!(h.colour(Some(f64::NAN), true), None);
    }
}
