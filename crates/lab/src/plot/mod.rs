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
//!
//! One module per kind of figure ([`line_plot`], [`heatmap`],
//! [`status_grid`]); axes and ticks (drawn with plotters' linear and
//! logarithmic coordinates) and the shared style in their own.

mod axis;
mod grid;
mod heatmap;
mod line;
mod style;

use std::ffi::OsString;
use std::fs;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

pub use self::grid::{Cell, CellStatus, StatusGrid, status_grid};
pub use self::heatmap::{Heatmap, heatmap};
pub use self::line::{LinePlot, Series, Vertical, line_plot};
use self::style::ensure_font;
pub use self::style::{Dash, Pen};

/// Refuses an axis label without its unit in brackets at its end
/// (`t [s]`, `N [kg]`, a pure number `c [–]`): every axis of every figure
/// says what it measures in.
fn check_units(labels: &[&str]) -> Result<(), String> {
    for l in labels {
        let unit = l
            .trim_end()
            .strip_suffix(']')
            .and_then(|s| s.rfind('[').map(|i| &s[i + 1..]));
        if unit.is_none_or(|u| u.trim().is_empty()) {
            return Err(format!(
                "axis label `{l}` has no unit: end it with one in brackets, e.g. `t [s]`, or `[–]` for a pure number"
            ));
        }
    }
    Ok(())
}

/// `<stem><ext>`, appending rather than replacing an extension.
fn with_suffix(stem: &Path, ext: &str) -> PathBuf {
    let mut s: OsString = stem.as_os_str().to_owned();
    s.push(ext);
    PathBuf::from(s)
}

/// Renders the PNG and the SVG of one figure of `size` pixels and writes
/// both atomically.
fn write_outputs(
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
