//! The figures of an experiment, drawn from its result files.
//!
//! For the plotted point: trajectories in the plane, divergence of every pair
//! against time, constraint residual and energy drift against time. For a
//! sweep: the divergence from the reference at the end of the common span
//! against one swept variable (a line per formulation) or two (a heat map per
//! formulation). Everything is read back from `points/` and `trajectories/`,
//! so `nonholo plot DIR` redraws without running anything.

use std::path::{Path, PathBuf};

use super::output::{Trajectory, trajectory_path};
use super::pens;
use super::point::PointResult;
use super::spec::{Experiment, SweepMode};
use crate::plot::{Heatmap, LinePlot, Series, heatmap, line_plot};

/// The residual axis: in the constraints' unit where there are only
/// nonholonomic ones (`max |g| [m/s]`); with holonomic ones the measure
/// mixes units (`f` in metres, `ḟ` in m/s) and says so.
fn residual_label(info: &nonholo_core::SceneInfo) -> String {
    match (info.k(), info.s(), info.nonholonomic_unit) {
        (0, s, u) if s > 0 && !u.is_empty() => format!("max |g| [{u}]"),
        _ => "max(|g|, |f|, |ḟ|) [units of each constraint]".into(),
    }
}

/// Up to this many formulations the divergence plot shows every pair; with
/// more, each against the reference.
const MAX_ALL_PAIRS: usize = 4;

/// Caption of a plot from its file stem, for the HTML page.
pub fn caption(exp: &Experiment, stem: &str) -> String {
    // `divergence-p1`: the figure of a `plots.also` point.
    let (stem, index) = match stem.rsplit_once("-p") {
        Some((s, i))
            if i.parse::<usize>()
                .is_ok_and(|i| exp.also_points.contains(&i)) =>
        {
            (s, i.parse().unwrap_or(exp.plot_point))
        }
        _ => (stem, exp.plot_point),
    };
    let mut point = format!("point {index}");
    if exp.log_time && stem != "trajectories" && !stem.starts_with("sweep-") {
        point.push_str(", logarithmic time axis");
    }
    match stem {
        "trajectories" => format!("Path of the first two coordinates, every formulation, {point}."),
        "divergence" => format!(
            "Divergence ‖(x, y)_a − (x, y)_b‖ of {} against time on the common output grid, {point} (log scale; a curve ends where one of the two runs stopped).",
            if exp.formulations.len() <= MAX_ALL_PAIRS && !exp.divergence_from_reference {
                "every pair".to_string()
            } else {
                format!("every formulation and the reference {}", exp.reference)
            }
        ),
        "residual" => {
            format!(
                "Constraint residual max(|g|, |f|, |ḟ|), the largest up to each output time, {point}."
            )
        }
        "energy" => {
            format!(
                "Energy drift |E(t) − E(0)|, E = q̇·∂L/∂q̇ − L, the largest up to each output time, {point}."
            )
        }
        s if s.starts_with("series-") => format!(
            "{} against time on the output grid (every {} s){}, every formulation, {point}; \
             a curve ends where its run stopped, and covers the curves listed before it in \
             the legend where they agree.",
            &s["series-".len()..],
            exp.output_every,
            exp.series_span
                .map(|[a, b]| format!(" from t = {a} to {b} s"))
                .unwrap_or_default()
        ),
        "minimise" => match &exp.minimise {
            Some(m) => format!(
                "The smallest distance of {} from {} at t = {} s over {} ∈ [{}, {}] at every point \
                 of the sweep: the smallest of {} samples (dashed) and after golden-section \
                 refinement of the {} best sampled local minima (solid); minima.csv has the values.",
                m.label,
                exp.reference,
                exp.t_end,
                m.over,
                m.range[0],
                m.range[1],
                m.samples,
                m.refine
            ),
            None => stem.to_string(),
        },
        "minimise-curve" => match &exp.minimise {
            Some(m) => format!(
                "The distance of {} from {} at t = {} s against {}, sampled on {} values, at \
                 {point}; the refined minimum marked. A narrower dip between two samples would be \
                 missed: a sampled minimum, not a proven one.",
                m.label, exp.reference, exp.t_end, m.over, m.samples
            ),
            None => stem.to_string(),
        },
        "sweep-evals" => format!(
            "Right-hand-side evaluations of every formulation over the sweep ({}): the cost that does not depend on the machine; runs that used up their budget are marked where they stopped, other failed runs left out (reasons in runs.csv).",
            exp.axes
                .iter()
                .map(|a| a.name.as_str())
                .collect::<Vec<_>>()
                .join(" × ")
        ),
        "sweep-switch" => format!(
            "The located time of each formulation's first change of mode (the friction realisation's stick–slip transitions, found as events on the integrator's continuous extension) over the sweep ({}); the legend names the transition; points without a switch on [0, {}] s are left out.",
            exp.axes
                .iter()
                .map(|a| a.name.as_str())
                .collect::<Vec<_>>()
                .join(" × "),
            exp.t_end
        ),
        "sweep-cost" => format!(
            "Wall time of every formulation over the sweep ({}), {}, while the other worker threads run other points (so it varies where the cost cannot; sweep-evals does not); runs that used up their budget are marked where they stopped, other failed runs left out (reasons in runs.csv).",
            exp.axes
                .iter()
                .map(|a| a.name.as_str())
                .collect::<Vec<_>>()
                .join(" × "),
            if exp.repeats > 1 {
                format!("the median of {} timed runs each", exp.repeats)
            } else {
                "one timed run each (differences of tens of per cent are noise)".to_string()
            }
        ),
        s if s.starts_with("sweep-") => format!(
            "Divergence from {} {}, over the sweep ({}); failed runs are left out (reasons in runs.csv); on logarithmic axes the legend gives the fitted slope.",
            exp.reference,
            if exp.sweep_max {
                "(the largest over the common span)"
            } else {
                "at the end of the common span"
            },
            exp.axes
                .iter()
                .map(|a| a.name.as_str())
                .collect::<Vec<_>>()
                .join(" × ")
        ),
        other => other.to_string(),
    }
}

/// `name [unit]` of a velocity-chart value, coordinate or velocity.
fn quantity_label(exp: &Experiment, name: &str) -> String {
    quantity_label_in(exp.scene_info().ok(), name)
}

/// `name [unit]` for a coordinate, `<coord>_dot` or velocity-chart value of
/// `scene` (`[–]` where it has no unit).
pub(crate) fn quantity_label_in(info: Option<&nonholo_core::SceneInfo>, name: &str) -> String {
    let Some(info) = info else {
        return format!("{name} [–]");
    };
    let unit = info
        .velocity_chart
        .iter()
        .chain(info.coordinates)
        .find(|c| c.name == name)
        .map(|c| c.unit.to_string())
        .or_else(|| {
            let c = name.strip_suffix("_dot")?;
            let u = info.coordinates.iter().find(|x| x.name == c)?.unit;
            Some(format!("{u}/s"))
        });
    match unit {
        Some(u) if !u.is_empty() => format!("{name} [{u}]"),
        _ => format!("{name} [–]"),
    }
}

fn coordinate_label(exp: &Experiment, k: usize) -> String {
    exp.scene_info()
        .ok()
        .and_then(|i| {
            i.coordinates
                .get(k)
                .map(|c| format!("{} [{}]", c.name, c.unit))
        })
        .unwrap_or_else(|| format!("q{k} [–]"))
}

/// Axis label of a swept name, from the quantity's name and unit: a scene
/// parameter or initial value shows its unit (`alpha [rad]`); a
/// formulation's own value says whose it is (`lambda of C [N·s]`), with the
/// unit that follows from the unit of the constraints (multipliers `J`
/// over it, the realisations' gains `k`, `N` by their definition).
pub(super) fn axis_label(exp: &Experiment, name: &str) -> String {
    let info = exp.scene_info().ok();
    let (owner, rest) = match name.split_once('.') {
        Some((l, r)) if exp.formulations.iter().any(|f| f.label == l) => (Some(l), r),
        _ => (None, name),
    };
    let short = rest
        .strip_prefix("param.")
        .or_else(|| rest.strip_prefix("init."))
        .or_else(|| rest.strip_prefix("option."))
        .unwrap_or(rest);
    let g_unit = info.map_or("", |i| i.nonholonomic_unit);
    let per_g = |numerator: &str| match g_unit {
        "" => String::new(),
        "m/s" => numerator.to_string(),
        u => format!("J/({u})"),
    };
    let unit: String = if rest.starts_with("init.") && short.starts_with("lambda") {
        per_g("N·s")
    } else if rest == "option.k" {
        per_g("kg/s")
    } else if rest == "option.N" {
        per_g("kg")
    } else if rest.starts_with("option.") {
        crate::formulations::ALL
            .iter()
            .flat_map(|f| f.options)
            .find(|o| o.name == short)
            .map_or("", |o| o.unit)
            .to_string()
    } else {
        info.and_then(|info| {
            if rest.starts_with("param.") {
                return info.params.iter().find(|p| p.name == short).map(|p| p.unit);
            }
            info.coordinates
                .iter()
                .chain(info.velocity_chart)
                .find(|c| c.name == short)
                .map(|c| c.unit)
        })
        .unwrap_or("")
        .to_string()
    };
    let whose = owner.map(|l| format!(" of {l}")).unwrap_or_default();
    // Every axis states its unit; a pure number (a slope `c`, a case name)
    // says so with [–].
    let unit = if unit.is_empty() {
        "–"
    } else {
        unit.as_str()
    };
    format!("{short}{whose} [{unit}]")
}

/// The trajectories of the plotted point: one for every formulation that
/// has samples there (a `t_last`). A missing or unreadable one is an error
/// naming the file: a figure is drawn from all of its data or not at all.
pub fn trajectories(
    exp: &Experiment,
    dir: &Path,
    results: &[PointResult],
    point: usize,
) -> Result<Vec<(String, Trajectory)>, String> {
    let Some(r) = results.iter().find(|r| r.index == point) else {
        return Ok(Vec::new());
    };
    r.body
        .formulations
        .iter()
        .filter(|f| f.t_last.is_some())
        .map(|f| {
            let p = trajectory_path(dir, point, &f.label);
            if !p.exists() {
                return Err(format!(
                    "{}: missing (trajectories are not committed: run `nonholo experiment {}` \
                     to compute the plotted point again)",
                    p.display(),
                    exp.path.display()
                ));
            }
            let t = Trajectory::read(&p)?;
            let info = exp.scene_info().map_err(|e| e.to_string())?;
            let needed = ["t", "residual", "energy"]
                .into_iter()
                .chain(info.coordinates.iter().map(|c| c.name))
                .chain(exp.series.iter().map(String::as_str));
            for c in needed {
                if t.column(c).is_none() {
                    return Err(format!("{}: no column `{c}`", p.display()));
                }
            }
            Ok((f.label.clone(), t))
        })
        .collect()
}

/// Draws every figure of `exp` into `dir/plots/`; returns the files written:
/// the time series of `plots.point`, those of every `plots.also` point (file
/// stems ending in `-p<i>`), and the figures over the sweep.
pub fn draw(exp: &Experiment, dir: &Path, results: &[PointResult]) -> Result<Vec<PathBuf>, String> {
    let mut files = time_series(exp, dir, results, exp.plot_point, "")?;
    for &i in &exp.also_points {
        files.extend(time_series(exp, dir, results, i, &format!("-p{i}"))?);
    }
    files.extend(sweep_plots(exp, &dir.join("plots"), results)?);
    if let Some(pair) = &exp.phase {
        files.extend(phase_portrait(exp, dir, results, pair)?);
    }
    if let Some(m) = &exp.minimise {
        files.extend(super::minimise::draw(exp, m, dir)?);
    }
    super::files::remove_other_figures(&dir.join("plots"), &files)?;
    Ok(files)
}

/// `pair[1]` against `pair[0]` along every trajectory of every point that
/// keeps its trajectories (all with `plots.all_trajectories`, else the
/// plotted ones): one figure per formulation (`phase-<label>`, in its
/// colour, since formulations conserving the same energy would hide each
/// other's curves), a dot at each start and a black dot at each end.
fn phase_portrait(
    exp: &Experiment,
    dir: &Path,
    results: &[PointResult],
    pair: &[String; 2],
) -> Result<Vec<PathBuf>, String> {
    let pens = pens::of_experiment(exp);
    let points: Vec<usize> = if exp.all_trajectories {
        results.iter().map(|r| r.index).collect()
    } else {
        std::iter::once(exp.plot_point)
            .chain(exp.also_points.iter().copied())
            .collect()
    };
    let mut by_label: Vec<(String, Vec<Series>)> = exp
        .formulations
        .iter()
        .map(|f| (f.label.clone(), Vec::new()))
        .collect();
    for p in points {
        for (label, t) in trajectories(exp, dir, results, p)? {
            let (Some(x), Some(y), Some(time)) =
                (t.column(&pair[0]), t.column(&pair[1]), t.column("t"))
            else {
                continue;
            };
            let Some((_, series)) = by_label.iter_mut().find(|(l, _)| *l == label) else {
                continue;
            };
            let (Some((&x0, &y0)), Some((xe, ye, te))) = (
                x.first().zip(y.first()),
                x.last()
                    .zip(y.last())
                    .zip(time.last())
                    .map(|((a, b), c)| (*a, *b, *c)),
            ) else {
                continue;
            };
            let pen = pens::find(&pens, &label);
            let first = series.is_empty();
            let named = |text: String| if first { text } else { String::new() };
            series.push(Series {
                label: named("start".into()),
                x: vec![x0],
                y: vec![y0],
                pen,
            });
            series.push(Series {
                label: named(format!("end (t = {} s)", crate::fields::num(te))),
                x: vec![xe],
                y: vec![ye],
                pen: Some(crate::plot::Pen {
                    colour: pens::colour_of(super::spec::CLOSED_FORM),
                    dash: crate::plot::Dash::Solid,
                }),
            });
            series.push(Series {
                label: String::new(),
                x,
                y,
                pen,
            });
        }
    }
    let mut files = Vec::new();
    for (label, series) in by_label {
        if series.is_empty() {
            continue;
        }
        let f = exp.formulations.iter().find(|f| f.label == label);
        let what = f.map_or(label.clone(), |f| format!("{label} ({})", f.formulation));
        files.extend(line_plot(
            &LinePlot {
                title: format!("{what}: {} against {}, every start", pair[1], pair[0]),
                x_label: quantity_label(exp, &pair[0]),
                y_label: quantity_label(exp, &pair[1]),
                series,
                ..LinePlot::default()
            },
            &dir.join("plots").join(format!("phase-{label}")),
        )?);
    }
    Ok(files)
}

/// The figures against time of one point (paths, divergence, residual,
/// energy, series), their file stems ending in `suffix`.
fn time_series(
    exp: &Experiment,
    dir: &Path,
    results: &[PointResult],
    point: usize,
    suffix: &str,
) -> Result<Vec<PathBuf>, String> {
    let plots = dir.join("plots");
    let mut files = Vec::new();
    let info = exp.scene_info().map_err(|e| e.to_string())?;
    let coords: Vec<String> = info
        .coordinates
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let angle: Vec<bool> = info.coordinates.iter().map(|c| c.unit == "rad").collect();

    let trajectories = trajectories(exp, dir, results, point)?;
    let pens = pens::of_experiment(exp);
    let describe = |label: &str| {
        exp.formulations
            .iter()
            .find(|f| f.label == label)
            .map(|f| {
                if f.formulation == super::spec::CLOSED_FORM {
                    format!("{label}: closed form")
                } else {
                    format!("{label}: {} ({})", f.formulation, f.settings.integrator)
                }
            })
            .unwrap_or_else(|| label.to_string())
    };
    // "at alpha = 0.3, a = 0.4" for the plotted point (nothing without a sweep).
    let values = results
        .iter()
        .find(|r| r.index == point)
        .map(|r| r.values.clone())
        .unwrap_or_default();
    let at = super::spec::compact(&exp.axes, &values);
    let at = if at.is_empty() {
        at
    } else {
        format!("at {at}")
    };
    let titled = |what: &str| {
        if at.is_empty() {
            what.to_string()
        } else {
            format!("{what} {at}")
        }
    };

    if !trajectories.is_empty() && coords.len() >= 2 {
        let series = trajectories
            .iter()
            .filter_map(|(l, t)| {
                Some(Series {
                    pen: pens::find(&pens, l),
                    label: describe(l),
                    x: t.column(&coords[0])?,
                    y: t.column(&coords[1])?,
                })
            })
            .collect();
        files.extend(line_plot(
            &LinePlot {
                verticals: Vec::new(),
                title: titled("Paths"),
                x_label: coordinate_label(exp, 0),
                y_label: coordinate_label(exp, 1),
                log_x: false,
                log_y: false,
                equal_aspect: true,
                series,
                y_range: None,
            },
            &plots.join(format!("{}{suffix}", "trajectories")),
        )?);

        // Divergence of every pair from the trajectories on the common grid,
        // in the colour of the second of the two.
        let mut series = Vec::new();
        let mut pair_pens = pens::Pens::default();
        // Beyond four formulations every pair would crowd the legend (36
        // lines for nine): only the pairs with the reference then.
        let all_pairs = trajectories.len() <= MAX_ALL_PAIRS && !exp.divergence_from_reference;
        for (i, (la, ta)) in trajectories.iter().enumerate() {
            for (lb, tb) in &trajectories[i + 1..] {
                if !all_pairs && la != &exp.reference && lb != &exp.reference {
                    continue;
                }
                let (Some(t_a), Some(t_b)) = (ta.column("t"), tb.column("t")) else {
                    continue;
                };
                let cols: Vec<(Vec<f64>, Vec<f64>)> = coords
                    .iter()
                    .take(2)
                    .filter_map(|c| Some((ta.column(c)?, tb.column(c)?)))
                    .collect();
                let n = super::point::common_len(&t_a, &t_b);
                // Runs from one state agree exactly at the start: that zero
                // is left out, not reported as a point off the log axis.
                let first = usize::from(n > 1 && cols.iter().all(|(a, b)| a[0] == b[0]));
                let y: Vec<f64> = (first..n)
                    .map(|j| {
                        cols.iter()
                            .enumerate()
                            .map(|(k, (a, b))| super::point::coord_diff(a[j] - b[j], angle[k]))
                            .map(|d| d * d)
                            .sum::<f64>()
                            .sqrt()
                    })
                    .collect();
                let line = exp.formulations.iter().find(|f| &f.label == lb);
                series.push(Series {
                    pen: line.map(|f| pair_pens.take(&f.formulation, &f.settings.integrator)),
                    label: format!("{la} vs {lb}"),
                    x: t_a[first..n].to_vec(),
                    y,
                });
            }
        }
        if !series.is_empty() {
            files.extend(line_plot(
                &LinePlot {
                    verticals: Vec::new(),
                    title: titled("Divergence"),
                    x_label: "t [s]".into(),
                    y_label: format!(
                        "‖Δ({}, {})‖ [{}]",
                        coords[0], coords[1], info.coordinates[0].unit
                    ),
                    log_x: exp.log_time,
                    log_y: true,
                    equal_aspect: false,
                    series,
                    y_range: None,
                },
                &plots.join(format!("{}{suffix}", "divergence")),
            )?);
        }

        let residual = trajectories
            .iter()
            .filter_map(|(l, t)| {
                Some(Series {
                    pen: pens::find(&pens, l),
                    label: describe(l),
                    x: t.column("t")?,
                    y: running_max(&t.column("residual")?),
                })
            })
            .collect();
        files.extend(line_plot(
            &LinePlot {
                verticals: Vec::new(),
                title: titled("Constraint residual, largest so far"),
                x_label: "t [s]".into(),
                y_label: residual_label(info),
                log_x: exp.log_time,
                log_y: true,
                equal_aspect: false,
                series: residual,
                y_range: None,
            },
            &plots.join(format!("{}{suffix}", "residual")),
        )?);
        let energy = trajectories
            .iter()
            .filter_map(|(l, t)| {
                let e = t.column("energy")?;
                let e0 = *e.first()?;
                Some(Series {
                    pen: pens::find(&pens, l),
                    label: describe(l),
                    x: t.column("t")?,
                    y: running_max(&e.iter().map(|v| (v - e0).abs()).collect::<Vec<_>>()),
                })
            })
            .collect();
        files.extend(line_plot(
            &LinePlot {
                verticals: Vec::new(),
                title: titled("Energy drift, largest so far"),
                x_label: "t [s]".into(),
                y_label: "|E(t) − E(0)| [J]".into(),
                log_x: exp.log_time,
                log_y: true,
                equal_aspect: false,
                series: energy,
                y_range: None,
            },
            &plots.join(format!("{}{suffix}", "energy")),
        )?);
        for name in &exp.series {
            let series = trajectories
                .iter()
                .filter_map(|(l, t)| {
                    let (x, y): (Vec<f64>, Vec<f64>) = t
                        .column("t")?
                        .into_iter()
                        .zip(t.column(name)?)
                        .filter(|(x, _)| exp.series_span.is_none_or(|[a, b]| *x >= a && *x <= b))
                        .unzip();
                    Some(Series {
                        pen: pens::find(&pens, l),
                        label: describe(l),
                        x,
                        y,
                    })
                })
                .collect();
            files.extend(line_plot(
                &LinePlot {
                    verticals: Vec::new(),
                    title: titled(&format!("{name} against time")),
                    x_label: "t [s]".into(),
                    y_label: quantity_label(exp, name),
                    log_x: exp.log_time,
                    log_y: false,
                    equal_aspect: false,
                    series,
                    y_range: None,
                },
                &plots.join(format!("series-{name}{suffix}")),
            )?);
        }
    }

    Ok(files)
}

/// The value of axis `k` at every point, as numbers (categories by index).
fn axis_numbers(exp: &Experiment, k: usize, results: &[PointResult]) -> (Vec<f64>, bool) {
    let parsed: Vec<Option<f64>> = results.iter().map(|r| r.values[k].parse().ok()).collect();
    if parsed.iter().all(Option::is_some) {
        (parsed.into_iter().map(|v| v.unwrap_or(0.0)).collect(), true)
    } else {
        let cats = &exp.axes[k].values;
        (
            results
                .iter()
                .map(|r| cats.iter().position(|c| c == &r.values[k]).unwrap_or(0) as f64)
                .collect(),
            false,
        )
    }
}

/// `max(v[0..=i])` for every `i` (NaN propagates): how a residual or a
/// drift grows, without the oscillation of its instantaneous value.
fn running_max(v: &[f64]) -> Vec<f64> {
    let mut m = 0.0f64;
    v.iter()
        .map(|&x| {
            m = nonholo_core::constraints::nan_max(m, x);
            m
        })
        .collect()
}

/// A numeric axis of positive values spanning more than two decades is drawn
/// logarithmically (gains `k`, `N`, tolerances).
fn log_axis(x: &[f64], numeric: bool) -> bool {
    let lo = x.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    numeric && lo > 0.0 && hi / lo > 100.0
}

/// Whether the positive values of `series` span more than two decades: then
/// a logarithmic axis (zeros are left out, and the legend says so);
/// otherwise a linear one, on which a zero (e.g. two formulations that
/// coincide) is drawn where it is.
fn spans_decades(series: &[Series]) -> bool {
    let positive: Vec<f64> = series
        .iter()
        .flat_map(|s| s.y.iter().copied())
        .filter(|v| v.is_finite() && *v > 0.0)
        .collect();
    log_axis(&positive, true)
}

/// The divergence of `label` from `reference` at the end of their common
/// span (the largest over it with `[plots] sweep_max`); none if either run
/// failed (its span ends where it failed, so the value would not be
/// comparable with the other points').
fn end_divergence(exp: &Experiment, r: &PointResult, label: &str) -> Option<f64> {
    let reference = exp.reference.as_str();
    let failed = |l: &str| {
        r.body
            .formulations
            .iter()
            .any(|f| f.label == l && f.status == "failed")
    };
    if failed(reference) || failed(label) {
        return None;
    }
    r.body
        .pairs
        .iter()
        .find(|p| (p.a == reference && p.b == label) || (p.b == reference && p.a == label))
        .and_then(|p| {
            if exp.sweep_max {
                p.div_xy_max
            } else {
                p.div_xy_end
            }
        })
}

/// Where the sweep figures read the divergence: "at t = 2 s" when every
/// pair with the reference spans the whole run, else "at the end of the
/// common span" (or the largest over it, `[plots] sweep_max`).
fn sweep_when(exp: &Experiment, results: &[PointResult]) -> String {
    if exp.sweep_max {
        return "largest over the common span".into();
    }
    let whole = results.iter().all(|r| {
        r.body
            .pairs
            .iter()
            .filter(|p| p.a == exp.reference || p.b == exp.reference)
            .all(|p| {
                p.span_end
                    .is_some_and(|t| (t - exp.t_end).abs() <= 1e-9 * exp.t_end.max(1.0))
            })
    });
    if whole {
        format!(
            "at t = {} s",
            crate::table::readable(&format!("{:e}", exp.t_end))
        )
    } else {
        "at the end of the common span".into()
    }
}

fn sweep_plots(
    exp: &Experiment,
    plots: &Path,
    results: &[PointResult],
) -> Result<Vec<PathBuf>, String> {
    let others: Vec<&str> = exp
        .formulations
        .iter()
        .map(|f| f.label.as_str())
        .filter(|l| *l != exp.reference)
        .collect();
    let mut files = Vec::new();
    let pens = pens::of_experiment(exp);
    if results.len() < 2 || others.is_empty() {
        return Ok(files);
    }
    match (exp.axes.len(), &exp.mode) {
        (1, _) | (_, SweepMode::Zip) => {
            let (x, numeric) = axis_numbers(exp, 0, results);
            // Two categories (e.g. the two potentials) make no curve: their
            // values are in the tables and the points' own figures.
            if !numeric && results.len() < 3 {
                return Ok(files);
            }
            let log_x = log_axis(&x, numeric);
            let mut order: Vec<usize> = (0..results.len()).collect();
            order.sort_by(|&a, &b| x[a].total_cmp(&x[b]));
            let series: Vec<Series> = others
                .iter()
                .map(|l| {
                    let pts: Vec<(f64, f64)> = order
                        .iter()
                        .filter_map(|&i| end_divergence(exp, &results[i], l).map(|d| (x[i], d)))
                        .collect();
                    let (px, py): (Vec<f64>, Vec<f64>) = pts.into_iter().unzip();
                    let mut label = format!("{l} vs {}", exp.reference);
                    if log_x && let Some(rate) = super::wp::log_slope(&px, &py) {
                        label.push_str(&format!(" (slope {rate:.2})"));
                    }
                    Series {
                        label,
                        x: px,
                        y: py,
                        pen: pens::find(&pens, l),
                    }
                })
                .collect();
            let axis = &exp.axes[0];
            let x_label = if numeric {
                axis_label(exp, &axis.name)
            } else {
                format!(
                    "{} ({})",
                    axis_label(exp, &axis.name),
                    axis.values.join(", ")
                )
            };
            let log_y = spans_decades(&series);
            files.extend(line_plot(
                &LinePlot {
                    verticals: Vec::new(),
                    title: format!(
                        "Divergence from {}, {}",
                        exp.reference,
                        sweep_when(exp, results)
                    ),
                    x_label: x_label.clone(),
                    y_label: format!("‖Δ(x, y)‖ from {} [m]", exp.reference),
                    log_x,
                    log_y,
                    equal_aspect: false,
                    series,
                    y_range: None,
                },
                &plots.join("sweep-end"),
            )?);
            // Cost over the sweep, e.g. explicit against implicit as
            // stiffness grows: wall time (machine-dependent, with the other
            // worker threads' runs beside it) and right-hand-side
            // evaluations (the same everywhere). Runs that used up their
            // budget are drawn apart (where they stopped, not a cost to the
            // end); other failed runs are left out.
            let cost = |value: &dyn Fn(&super::FormResult) -> Option<f64>| -> Vec<Series> {
                let mut out = Vec::new();
                for f in exp
                    .formulations
                    .iter()
                    .filter(|f| f.formulation != super::spec::CLOSED_FORM)
                {
                    let pick = |budget: bool| -> (Vec<f64>, Vec<f64>) {
                        order
                            .iter()
                            .filter_map(|&i| {
                                let r = results[i]
                                    .body
                                    .formulations
                                    .iter()
                                    .find(|g| g.label == f.label)?;
                                let over =
                                    r.status == "failed" && super::budget_stop(r.error.as_deref());
                                let keep = if budget { over } else { r.status != "failed" };
                                if keep {
                                    value(r).map(|v| (x[i], v))
                                } else {
                                    None
                                }
                            })
                            .unzip()
                    };
                    let pen = pens::find(&pens, &f.label);
                    let name =
                        format!("{}: {} ({})", f.label, f.formulation, f.settings.integrator);
                    let (px, py) = pick(false);
                    out.push(Series {
                        label: name.clone(),
                        x: px,
                        y: py,
                        pen,
                    });
                    let (bx, by) = pick(true);
                    if !bx.is_empty() {
                        out.push(Series {
                            label: format!("{name}: budget used up, where it stopped"),
                            x: bx,
                            y: by,
                            pen: pen.map(|p| crate::plot::Pen {
                                dash: crate::plot::Dash::LongDash,
                                ..p
                            }),
                        });
                    }
                }
                out
            };
            let time = cost(&|r| (r.wall_time_stop_t.is_none()).then_some(r.wall_time_s));
            files.extend(line_plot(
                &LinePlot {
                    verticals: Vec::new(),
                    title: "Cost over the sweep: wall time".into(),
                    x_label: x_label.clone(),
                    y_label: "wall time [s]".into(),
                    log_x,
                    log_y: spans_decades(&time),
                    equal_aspect: false,
                    series: time,
                    y_range: None,
                },
                &plots.join("sweep-cost"),
            )?);
            let evals = cost(&|r| {
                (r.wall_time_stop_t.is_none() && r.counters.rhs_evals > 0)
                    .then_some(r.counters.rhs_evals as f64)
            });
            files.extend(line_plot(
                &LinePlot {
                    verticals: Vec::new(),
                    title: "Cost over the sweep: evaluations".into(),
                    x_label: x_label.clone(),
                    y_label: "right-hand-side evaluations [count]".into(),
                    log_x,
                    log_y: spans_decades(&evals),
                    equal_aspect: false,
                    series: evals,
                    y_range: None,
                },
                &plots.join("sweep-evals"),
            )?);
            // Where the formulations with modes first change it: one curve
            // per formulation and kind of change (a slip from the start
            // that reverses is not a slip onset).
            let mut switch = Vec::new();
            for f in &exp.formulations {
                let rows: Vec<(f64, f64, &str)> = order
                    .iter()
                    .filter_map(|&i| {
                        let r = results[i]
                            .body
                            .formulations
                            .iter()
                            .find(|g| g.label == f.label)?;
                        Some((x[i], r.first_switch_t?, r.first_switch.as_deref()?))
                    })
                    .collect();
                let mut kinds: Vec<&str> = rows.iter().map(|r| r.2).collect();
                kinds.sort_unstable();
                kinds.dedup();
                for (k, kind) in kinds.iter().enumerate() {
                    let (px, py): (Vec<f64>, Vec<f64>) = rows
                        .iter()
                        .filter(|r| r.2 == *kind)
                        .map(|r| (r.0, r.1))
                        .unzip();
                    let mut label = format!("{}: first switch {kind}", f.label);
                    if log_x && let Some(rate) = super::wp::log_slope(&px, &py) {
                        label.push_str(&format!(" (slope {rate:.2})"));
                    }
                    let pen = pens::find(&pens, &f.label).map(|p| crate::plot::Pen {
                        dash: if k == 0 {
                            p.dash
                        } else {
                            crate::plot::Dash::LongDash
                        },
                        ..p
                    });
                    switch.push(Series {
                        label,
                        x: px,
                        y: py,
                        pen,
                    });
                }
            }
            if !switch.is_empty() {
                files.extend(line_plot(
                    &LinePlot {
                        verticals: Vec::new(),
                        title: "First change of mode over the sweep".into(),
                        x_label,
                        y_label: "time of the first switch [s]".into(),
                        log_x,
                        log_y: spans_decades(&switch),
                        equal_aspect: false,
                        series: switch,
                        y_range: None,
                    },
                    &plots.join("sweep-switch"),
                )?);
            }
        }
        (2, SweepMode::Grid) => {
            let (xs, _) = axis_numbers(exp, 0, results);
            let (ys, _) = axis_numbers(exp, 1, results);
            let mut xv: Vec<f64> = xs.clone();
            xv.sort_by(f64::total_cmp);
            xv.dedup();
            let mut yv: Vec<f64> = ys.clone();
            yv.sort_by(f64::total_cmp);
            yv.dedup();
            for l in &others {
                let mut z = vec![vec![None; xv.len()]; yv.len()];
                for (i, r) in results.iter().enumerate() {
                    let xi = xv.iter().position(|v| *v == xs[i]);
                    let yi = yv.iter().position(|v| *v == ys[i]);
                    if let (Some(xi), Some(yi)) = (xi, yi) {
                        z[yi][xi] = end_divergence(exp, r, l);
                    }
                }
                files.extend(heatmap(
                    &Heatmap {
                        title: format!("{l} vs {}, {}", exp.reference, sweep_when(exp, results)),
                        x_label: axis_label(exp, &exp.axes[0].name),
                        y_label: axis_label(exp, &exp.axes[1].name),
                        z_label: "‖Δ(x, y)‖ [m]".into(),
                        x: xv.clone(),
                        y: yv.clone(),
                        z,
                        log_z: true,
                    },
                    &plots.join(format!("sweep-{l}")),
                )?);
            }
        }
        _ => {}
    }
    Ok(files)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    /// Every swept name of the experiment files gets its quantity and unit.
    #[test]
    fn axis_labels_carry_units() {
        let text = r#"[experiment]
name = "labels"
title = "t"
claim = "c"
scene = "sleigh-incline"

[init]
u = 2

[time]
t_end = 1.0
output_every = 0.1

[[formulation]]
label = "C"
formulation = "vakonomic"

[[formulation]]
label = "V"
formulation = "visc"

[[formulation]]
label = "M"
formulation = "mass"
"#;
        let exp = Experiment::parse(Path::new("experiments/labels.toml"), text).unwrap();
        for (name, label) in [
            ("param.alpha", "alpha [rad]"),
            ("init.u", "u [m/s]"),
            ("C.init.lambda", "lambda of C [N·s]"),
            ("V.option.k", "k of V [kg/s]"),
            ("M.option.N", "N of M [kg]"),
            ("option.k", "k [kg/s]"),
            ("C.rtol", "rtol of C [–]"),
            ("case", "case [–]"),
        ] {
            assert_eq!(axis_label(&exp, name), label, "{name}");
        }
    }
}
