//! `[minimise]`: at every point of a compare sweep, the distance of one
//! formulation from the reference at `t_end`, minimised over one more swept
//! name (C's `λ(0)`, say).
//!
//! The objective `d(v) = ‖(x, y)_label(t_end) − (x, y)_reference(t_end)‖`
//! (the first two coordinates, angles wrapped) is sampled on a uniform grid
//! of `samples` values over `range`; the `refine` smallest sampled local
//! minima are then refined by golden-section search inside the bracket of
//! their two grid neighbours. A value whose run does not reach `t_end`
//! leaves the objective undefined there (counted, and treated as +∞ by the
//! search). What this finds is the smallest distance *found*: a narrower
//! dip between two samples can be missed, and the pages say so.
//!
//! Files (recomputed by every run of the experiment; `nonholo plot` redraws
//! from them):
//!
//! | file | content |
//! |---|---|
//! | `minima.csv` | per point: the state's swept values, the refined and the grid minimum (value, distance), grid step, evaluations, undefined samples |
//! | `minimise/<point>.csv` | the sampled objective: `value,distance` (empty where undefined) |
//! | `plots/minimise.png` | the smallest distance found at every point |
//! | `plots/minimise-curve.png` | the sampled objective at `plots.point`, its minimum marked |

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::Serialize;

use super::files::write;
use super::pens;
use super::point::coord_diff;
use super::spec::{Experiment, MinimiseSpec};
use super::sweep::{Point, resolve};
use crate::plot::{LinePlot, Series, line_plot};
use crate::simulate::execute;
use crate::table::{self, Table, plain, plain_opt};

/// Directory of the sampled objectives.
pub const CURVES: &str = "minimise";
/// The file of minima.
pub const MINIMA: &str = "minima.csv";

/// The minimum found at one point (a row of `minima.csv` after the point
/// and its swept values).
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct Minimum {
    #[serde(skip)]
    pub point: usize,
    /// The refined minimiser and the distance there (none if the objective
    /// was undefined everywhere).
    #[serde(serialize_with = "plain_opt")]
    pub best: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    pub distance: Option<f64>,
    /// The smallest sample.
    #[serde(serialize_with = "plain_opt")]
    pub grid_best: Option<f64>,
    #[serde(serialize_with = "plain_opt")]
    pub grid_distance: Option<f64>,
    #[serde(serialize_with = "plain")]
    pub grid_step: f64,
    /// Runs of the formulation made (samples and refinement).
    pub evaluations: usize,
    /// Samples where its run, or the reference's, did not reach `t_end`.
    pub undefined: usize,
    /// Why nothing could be computed at this point (the reference failed).
    pub error: Option<String>,
}

/// `(x, y)` at `t_end` of the run `label` of `point` (of `exp` as given);
/// none if it does not reach `t_end`.
fn end_xy(exp: &Experiment, point: &Point, label: &str) -> Result<Option<[f64; 2]>, String> {
    let runs = resolve(exp, point)?;
    let run = runs
        .iter()
        .find(|r| r.label == label)
        .ok_or_else(|| format!("no formulation `{label}`"))?;
    if run.spec.formulation == super::spec::CLOSED_FORM {
        return Err("the minimisation needs integrated formulations, not a closed form".into());
    }
    let Ok((r, _)) = execute(&run.spec) else {
        return Ok(None);
    };
    let reached = r.failure.is_none() && r.solution.t_last >= exp.t_end * (1.0 - 1e-12);
    Ok(r.samples
        .last()
        .filter(|_| reached)
        .filter(|o| o.q.len() >= 2 && o.q[0].is_finite() && o.q[1].is_finite())
        .map(|o| [o.q[0], o.q[1]]))
}

/// Golden-section search for a minimum of `f` in `[a, b]`, down to a
/// bracket of `width`; returns the best value seen and the number of
/// evaluations.
fn golden(
    mut a: f64,
    mut b: f64,
    width: f64,
    f: &mut dyn FnMut(f64) -> f64,
) -> ((f64, f64), usize) {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - r * (b - a), a + r * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    let mut n = 2;
    let mut best = if fc <= fd { (c, fc) } else { (d, fd) };
    while (b - a).abs() > width && n < 200 {
        if fc <= fd {
            b = d;
            (d, fd) = (c, fc);
            c = b - r * (b - a);
            fc = f(c);
            if fc < best.1 {
                best = (c, fc);
            }
        } else {
            a = c;
            (c, fc) = (d, fd);
            d = a + r * (b - a);
            fd = f(d);
            if fd < best.1 {
                best = (d, fd);
            }
        }
        n += 1;
    }
    (best, n)
}

/// The minimisation at one point; writes its sampled objective.
fn at_point(exp: &Experiment, m: &MinimiseSpec, point: &Point, dir: &Path) -> Minimum {
    let [lo, hi] = m.range;
    let step = (hi - lo) / (m.samples - 1) as f64;
    let mut out = Minimum {
        point: point.index,
        best: None,
        distance: None,
        grid_best: None,
        grid_distance: None,
        grid_step: step,
        evaluations: 0,
        undefined: 0,
        error: None,
    };
    let angles: Vec<bool> = exp
        .scene_info()
        .map(|i| {
            i.coordinates
                .iter()
                .take(2)
                .map(|c| c.unit == "rad")
                .collect()
        })
        .unwrap_or_default();
    let reference = match end_xy(exp, point, &exp.reference) {
        Ok(Some(xy)) => xy,
        Ok(None) => {
            out.error = Some(format!(
                "the reference {} does not reach t_end",
                exp.reference
            ));
            return out;
        }
        Err(e) => {
            out.error = Some(e);
            return out;
        }
    };
    let mut evaluations = 0;
    let mut objective = |v: f64| -> Option<f64> {
        evaluations += 1;
        let (e, p) = m.at(exp, point, v);
        let xy = end_xy(&e, &p, &m.label).ok().flatten()?;
        let d: f64 = (0..2)
            .map(|k| {
                coord_diff(
                    xy[k] - reference[k],
                    angles.get(k).copied().unwrap_or(false),
                )
            })
            .map(|d| d * d)
            .sum::<f64>()
            .sqrt();
        d.is_finite().then_some(d)
    };
    let xs: Vec<f64> = (0..m.samples).map(|i| lo + step * i as f64).collect();
    let ds: Vec<Option<f64>> = xs.iter().map(|&v| objective(v)).collect();
    out.undefined = ds.iter().filter(|d| d.is_none()).count();
    let key = |d: Option<f64>| d.unwrap_or(f64::INFINITY);
    // Sampled local minima, smallest first.
    let mut minima: Vec<usize> = (0..xs.len())
        .filter(|&i| ds[i].is_some())
        .filter(|&i| {
            let left = i
                .checked_sub(1)
                .map(|j| key(ds[j]))
                .unwrap_or(f64::INFINITY);
            let right = ds.get(i + 1).map(|d| key(*d)).unwrap_or(f64::INFINITY);
            key(ds[i]) <= left && key(ds[i]) <= right
        })
        .collect();
    minima.sort_by(|&a, &b| key(ds[a]).total_cmp(&key(ds[b])));
    if let Some(&i) = minima.first() {
        out.grid_best = Some(xs[i]);
        out.grid_distance = ds[i];
        out.best = Some(xs[i]);
        out.distance = ds[i];
    }
    for &i in minima.iter().take(m.refine) {
        let a = if i == 0 { xs[0] } else { xs[i - 1] };
        let b = if i + 1 == xs.len() { xs[i] } else { xs[i + 1] };
        let ((v, d), _) = golden(a, b, 1e-9 * (hi - lo), &mut |v| key(objective(v)));
        if d < out.distance.unwrap_or(f64::INFINITY) {
            out.best = Some(v);
            out.distance = Some(d);
        }
    }
    out.evaluations = evaluations;
    let mut csv = String::from("value,distance\n");
    for (x, d) in xs.iter().zip(&ds) {
        csv.push_str(&format!(
            "{},{}\n",
            table::Plain::text(*x),
            d.map(table::Plain::text).unwrap_or_default()
        ));
    }
    if let Err(e) = write(&curve_path(dir, point.index), csv.as_bytes()) {
        out.error = Some(e);
    }
    out
}

fn curve_path(dir: &Path, point: usize) -> PathBuf {
    dir.join(CURVES).join(format!("{point}.csv"))
}

/// Runs the minimisation at every point (in parallel, on the caller's
/// thread pool) and writes `minima.csv` and the sampled objectives.
pub fn run(
    exp: &Experiment,
    m: &MinimiseSpec,
    dir: &Path,
    points: &[Point],
) -> Result<Vec<Minimum>, String> {
    std::fs::create_dir_all(dir.join(CURVES))
        .map_err(|e| format!("cannot create {}: {e}", dir.join(CURVES).display()))?;
    let minima: Vec<Minimum> = points
        .par_iter()
        .map(|p| at_point(exp, m, p, dir))
        .collect();
    let mut t = Table::per_point::<Minimum>(exp.axes.iter().map(|a| a.name.as_str()))?;
    for (mm, p) in minima.iter().zip(points) {
        t.at_point(p.index, &p.values, mm)?;
    }
    t.write(&dir.join(MINIMA))?;
    Ok(minima)
}

/// The rows of a CSV file as named fields.
fn read_rows(path: &Path) -> Result<Vec<std::collections::HashMap<String, String>>, String> {
    if !path.is_file() {
        return Err(format!(
            "{}: missing (run the experiment to compute it)",
            path.display()
        ));
    }
    let (header, records) = crate::table::read_csv(path)?;
    Ok(records
        .iter()
        .map(|r| {
            header
                .iter()
                .cloned()
                .zip(r.iter().map(String::from))
                .collect()
        })
        .collect())
}

/// For `summary.json`: over which name, the smallest and the largest of the
/// minima found over the points (point, minimiser, distance) and how many
/// points had none; `null` without a minimisation or its file.
pub fn summary(exp: &Experiment, dir: &Path) -> serde_json::Value {
    let Some(m) = &exp.minimise else {
        return serde_json::Value::Null;
    };
    let Ok(rows) = read_rows(&dir.join(MINIMA)) else {
        return serde_json::Value::Null;
    };
    let found: Vec<(f64, f64, f64)> = rows
        .iter()
        .filter_map(|r| {
            Some((
                r.get("point")?.parse().ok()?,
                r.get("best")?.parse().ok()?,
                r.get("distance")?.parse().ok()?,
            ))
        })
        .collect();
    let pick = |largest: bool| {
        found
            .iter()
            .copied()
            .reduce(|a, b| if (b.2 > a.2) == largest { b } else { a })
            .map(|(p, v, d)| serde_json::json!({"point": p as usize, "value": v, "distance": d}))
    };
    serde_json::json!({
        "over": m.over,
        "label": m.label,
        "reference": exp.reference,
        "t": exp.t_end,
        "samples": m.samples,
        "refine": m.refine,
        "smallest": pick(false),
        "largest": pick(true),
        "points_without_minimum": rows.len() - found.len(),
    })
}

/// Reads the sampled objective of `point`.
fn read_curve(dir: &Path, point: usize) -> Result<(Vec<f64>, Vec<f64>), String> {
    let path = curve_path(dir, point);
    let rows = read_rows(&path)?;
    let value = |r: &std::collections::HashMap<String, String>, k: &str| {
        r.get(k).and_then(|v| v.parse().ok()).unwrap_or(f64::NAN)
    };
    // An undefined distance is an empty field: NaN, left out of the figure.
    Ok(rows
        .iter()
        .map(|r| (value(r, "value"), value(r, "distance")))
        .unzip())
}

/// The figures of the minimisation, from the written files.
pub fn draw(exp: &Experiment, m: &MinimiseSpec, dir: &Path) -> Result<Vec<PathBuf>, String> {
    let plots = dir.join("plots");
    let pen = pens::find(&pens::of_experiment(exp), &m.label);
    let mut files = Vec::new();
    let rows = read_rows(&dir.join(MINIMA))?;
    let column = |name: &str| -> Vec<f64> {
        rows.iter()
            .map(|r| r.get(name).and_then(|v| v.parse().ok()).unwrap_or(f64::NAN))
            .collect()
    };
    let points = column("point");
    let (refined, grid) = (column("distance"), column("grid_distance"));
    let what = format!("{} vs {}", m.label, exp.reference);
    files.extend(line_plot(
        &LinePlot {
            verticals: Vec::new(),
            title: format!(
                "Smallest distance of {} from {} at every point",
                m.label, exp.reference
            ),
            x_label: "point of the sweep (see minima.csv) [–]".into(),
            y_label: format!("min ‖Δ(x, y)‖ at t = {} s [m]", exp.t_end),
            log_x: false,
            log_y: true,
            equal_aspect: false,
            series: vec![
                Series {
                    label: format!("{what}: refined minimum"),
                    x: points.clone(),
                    y: refined,
                    pen,
                },
                Series {
                    label: format!("{what}: smallest of {} samples", m.samples),
                    x: points,
                    y: grid,
                    pen: pen.map(|p| crate::plot::Pen {
                        dash: crate::plot::Dash::Dashed,
                        ..p
                    }),
                },
            ],
            y_range: None,
        },
        &plots.join("minimise"),
    )?);
    let point = exp.plot_point;
    let (xs, ds) = read_curve(dir, point)?;
    let best = rows
        .iter()
        .find(|r| r.get("point").map(String::as_str) == Some(&point.to_string()))
        .and_then(|r| {
            Some((
                r.get("best")?.parse().ok()?,
                r.get("distance")?.parse().ok()?,
            ))
        });
    let mut series = vec![Series {
        label: format!(
            "{what}, sampled every {}",
            table::readable(&format!(
                "{:e}",
                (m.range[1] - m.range[0]) / (m.samples - 1) as f64
            ))
        ),
        x: xs,
        y: ds,
        pen,
    }];
    if let Some((b, d)) = best {
        series.push(Series {
            label: format!(
                "refined minimum: {} m at {}",
                table::readable(&format!("{d:e}")),
                table::readable(&format!("{b:e}"))
            ),
            x: vec![b],
            y: vec![d],
            // The formulation's colour, drawn as an open circle.
            pen: pen.map(|p| crate::plot::Pen {
                dash: crate::plot::Dash::Dashed,
                ..p
            }),
        });
    }
    files.extend(line_plot(
        &LinePlot {
            verticals: Vec::new(),
            title: format!(
                "{} from {} at t = {} s, point {point}",
                m.label, exp.reference, exp.t_end
            ),
            x_label: super::plots::axis_label(exp, &m.over),
            y_label: format!("‖Δ(x, y)‖ from {} [m]", exp.reference),
            log_x: false,
            log_y: true,
            equal_aspect: false,
            series,
            y_range: None,
        },
        &plots.join("minimise-curve"),
    )?);
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::golden;

    #[test]
    fn golden_section_finds_a_parabola_minimum() {
        let mut n = 0;
        let ((x, fx), evals) = golden(0.0, 3.0, 1e-10, &mut |x| {
            n += 1;
            (x - 1.234).powi(2) + 0.5
        });
        assert!((x - 1.234).abs() < 1e-8, "{x}");
        assert!((fx - 0.5).abs() < 1e-15);
        assert_eq!(evals, n);
        // The bracket shrinks by 0.618 per evaluation: ~50 for 3 → 1e-10.
        assert!(evals < 60, "{evals}");
    }
}
