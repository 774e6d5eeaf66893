//! The look shared by every figure: size, fonts, text sizes, line widths,
//! the series palette.

use std::sync::OnceLock;

use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

pub(super) const SIZE: (u32, u32) = (1200, 800);
pub(super) const FONT: &str = "sans-serif";
pub(super) const TITLE_PX: f64 = 33.0;
pub(super) const LABEL_PX: f64 = 28.0;
pub(super) const LEGEND_PX: f64 = 26.0;
pub(super) const TICK_PX: f64 = 24.0;
pub(super) const NOTE_PX: f64 = 26.0;
pub(super) const LINE_PX: u32 = 3;
pub(super) const MARKER_PX: i32 = 5;
/// Series with at most this many points also get a dot per point.
pub(super) const MARKER_MAX_POINTS: usize = 40;
pub(super) const TICK_MARK_PX: i32 = 6;
/// Width of the legend's line sample, including the gap before the text.
pub(super) const LEGEND_SAMPLE_PX: u32 = 56;
pub(super) const LEGEND_MARGIN_PX: u32 = 10;
/// Width of the heatmap's colour bar.
pub(super) const COLOUR_BAR_PX: u32 = 50;
/// Side of the grey square explaining missing heatmap cells.
pub(super) const SWATCH_PX: u32 = 26;

/// Okabe & Ito's colour-blind-safe palette, without its yellow (too pale on
/// white): blue, vermillion, bluish green, reddish purple, orange, sky blue,
/// black.
pub(super) const PALETTE: [RGBColor; 7] = [
    RGBColor(0, 114, 178),
    RGBColor(213, 94, 0),
    RGBColor(0, 158, 115),
    RGBColor(204, 121, 167),
    RGBColor(230, 159, 0),
    RGBColor(86, 180, 233),
    RGBColor(0, 0, 0),
];

/// Fill of heatmap cells without a drawable value.
pub(super) const MISSING_FILL: RGBColor = RGBColor(170, 170, 170);
/// Cross drawn over heatmap cells without a drawable value.
pub(super) const MISSING_CROSS: RGBColor = RGBColor(90, 90, 90);

/// A line's dash pattern.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Dash {
    #[default]
    Solid,
    Dashed,
    Dotted,
    LongDash,
}

impl Dash {
    /// Every pattern, in the order they are handed out.
    pub const ALL: [Dash; 4] = [Dash::Solid, Dash::Dashed, Dash::Dotted, Dash::LongDash];

    /// `(dash, gap)` in pixels on the plot (`None`: solid).
    pub(super) fn on_plot(self) -> Option<(u32, u32)> {
        match self {
            Dash::Solid => None,
            Dash::Dashed => Some((14, 8)),
            Dash::Dotted => Some((4, 7)),
            Dash::LongDash => Some((30, 9)),
        }
    }

    /// `(dash, gap)` in pixels in a legend sample (shorter than on the plot,
    /// so that the sample shows the pattern).
    pub(super) fn in_legend(self) -> Option<(u32, u32)> {
        match self {
            Dash::Solid => None,
            Dash::Dashed => Some((9, 5)),
            Dash::Dotted => Some((3, 5)),
            Dash::LongDash => Some((18, 5)),
        }
    }
}

/// How a series is drawn: a colour of [`PALETTE`] (by index) and a dash
/// pattern. Callers that give a meaning to colours (one per formulation)
/// set it; without one a series is drawn by its position.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pen {
    pub colour: usize,
    pub dash: Dash,
}

impl Pen {
    /// The pen of the `k`-th series without a pen of its own: the palette
    /// in order, then again dashed.
    pub(super) fn by_position(k: usize) -> Pen {
        Pen {
            colour: k % PALETTE.len(),
            dash: if (k / PALETTE.len()) % 2 == 1 {
                Dash::Dashed
            } else {
                Dash::Solid
            },
        }
    }

    pub(super) fn rgb(self) -> RGBColor {
        PALETTE[self.colour % PALETTE.len()]
    }
}

pub(super) fn text(px: f64) -> TextStyle<'static> {
    (FONT, px).into_font().into()
}

fn title_text(px: f64) -> TextStyle<'static> {
    (FONT, px, FontStyle::Bold).into_font().into()
}

/// `area` with `title` above it, in the title font shrunk (to no less than
/// half its size) where the title would be wider than the area.
pub(super) fn titled<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
) -> Result<DrawingArea<DB, plotters::coord::Shift>, String> {
    let room = f64::from(area.dim_in_pixel().0);
    let wide = f64::from(
        area.estimate_text_size(title, &title_text(TITLE_PX))
            .map_err(draw_err)?
            .0,
    );
    let px = if wide > room {
        (TITLE_PX * room / wide).floor().max(TITLE_PX / 2.0)
    } else {
        TITLE_PX
    };
    area.titled(title, title_text(px)).map_err(draw_err)
}

/// Registers DejaVu Sans (regular and bold) as `sans-serif`, once per
/// process.
pub(super) fn ensure_font() -> Result<(), String> {
    static REGISTERED: OnceLock<Result<(), String>> = OnceLock::new();
    REGISTERED
        .get_or_init(|| {
            register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
                .and_then(|_| register_font(FONT, FontStyle::Bold, dejavu::sans::bold()))
                .map_err(|_| "cannot load the bundled DejaVu Sans font".to_string())
        })
        .clone()
}

pub(super) fn draw_err(e: impl std::fmt::Display) -> String {
    format!("drawing the plot failed: {e}")
}
