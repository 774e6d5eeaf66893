//! Status grids: a table drawn as a figure, each cell coloured by how a run
//! ended (the stability map of a catalogue of cases).

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::style::{LEGEND_PX, SIZE, SWATCH_PX, TICK_PX, draw_err, ensure_font, text, titled};
use super::write_outputs;

/// How a cell of a [`StatusGrid`] ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellStatus {
    /// Ran to the end.
    Completed,
    /// Stopped where the formulation stops by design (a singular set).
    Stopped,
    /// Used up its step or wall-time budget (the designed end of an
    /// explicit method on a stiff problem).
    Budget,
    /// Failed (integrator error, set-up error).
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

const STATUS_FILL: [(CellStatus, RGBColor, &str); 5] = [
    (CellStatus::Completed, RGBColor(198, 232, 190), "completed"),
    (
        CellStatus::Stopped,
        RGBColor(253, 222, 160),
        "stopped at a singular set",
    ),
    (
        CellStatus::Budget,
        RGBColor(200, 214, 240),
        "budget used up",
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
    // The headers are measured in the font: registered first.
    ensure_font()?;
    let size = (SIZE.0, grid_height(g));
    write_outputs(
        stem,
        size,
        |root| draw_status_grid(&root, g),
        |root| draw_status_grid(&root, g),
    )
}

const GRID_ROW_PX: u32 = 52;

/// Height of the column headers: the longest name (drawn vertically), as
/// the legend font measures it (a one-pixel bitmap lends the measuring; the
/// font is registered before any figure is drawn).
fn grid_header_px(g: &StatusGrid) -> u32 {
    let mut pixel = [0u8; 3];
    let area = BitMapBackend::with_buffer(&mut pixel, (1, 1)).into_drawing_area();
    let style = text(LEGEND_PX);
    let longest = g
        .columns
        .iter()
        .filter_map(|c| area.estimate_text_size(c, &style).ok())
        .map(|(w, _)| w)
        .max()
        .unwrap_or(0);
    longest + 24
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
    let area = titled(&root.margin(8, 8, 8, 8), &g.title)?;
    let (aw, _) = area.dim_in_pixel();
    let label = text(LEGEND_PX);
    let small = text(TICK_PX);
    // Row names are drawn in the legend font: measured in it.
    let mut row_w = 0;
    for name in &g.rows {
        row_w = row_w.max(area.estimate_text_size(name, &label).map_err(draw_err)?.0);
    }
    let row_w = row_w + 24;
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
            // Text wider than its cell goes on two lines, split after its
            // first comma ("9.3," over "t=0.97").
            let (w, _) = area
                .estimate_text_size(&cell.text, &small)
                .map_err(draw_err)?;
            let lines: Vec<String> = match cell.text.split_once(", ") {
                Some((a, b)) if w as i32 > col_w - 8 => vec![format!("{a},"), b.to_string()],
                _ => vec![cell.text.clone()],
            };
            let step = row_h / 4;
            let first = y + row_h / 2 - step * (lines.len() as i32 - 1);
            for (i, line) in lines.into_iter().enumerate() {
                area.draw(&Text::new(
                    line,
                    (x + col_w / 2, first + 2 * step * i as i32),
                    small.pos(Pos::new(HPos::Center, VPos::Center)),
                ))
                .map_err(draw_err)?;
            }
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
