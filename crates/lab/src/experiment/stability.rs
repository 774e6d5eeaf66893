//! Experiments of kind `stability`: every formulation linearised about a
//! steady motion at evenly spread values of one steady value or parameter
//! (`[stability]`, [`super::spec::StabilitySpec`]), the eigenvalues drawn
//! against it and the values where an eigenvalue's real part crosses zero
//! located by bisection (docs/stability.md).
//!
//! | file | content |
//! |---|---|
//! | `stability.json` | every spectrum, error and crossing (what `nonholo plot` redraws from) |
//! | `eigenvalues.csv` | one row per (line, value, eigenvalue): real and imaginary part |
//! | `samples.csv` | one row per (line, value): status, unstable count, spectral abscissa, error |
//! | `crossings.csv` | one row per located crossing: value, unstable count below and above, real or complex |
//! | `summary.json`, `manifest.json`, `plots/`, `index.html` | as for the other kinds |
//!
//! A linearisation costs milliseconds, so nothing is stored per point and
//! a run computes everything again.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::files::{remove_other_figures, write_json};
use super::manifest::write_manifest;
use super::page::Page;
use super::spec::{Experiment, StabilitySpec, override_with};
use super::{Outcome, RunOptions};
use crate::CliError;
use crate::linearize::linearise_at;
use crate::plot::{Dash, LinePlot, Pen, Series, Vertical, line_plot};
use crate::table::{self, Table};

/// Schema of `stability.json`.
pub const SCHEMA: &str = "nonholo.stability/1";

/// Eigenvalues of modulus below this (relative to the largest, at least 1)
/// count as zero, and so do real parts below it: structural zeros come out
/// at 1e-15 (a cyclic speed) to 1e-14 (C's repeated zeros), and a crossing
/// located by bisection is not affected by the level.
const ZERO: f64 = 1e-9;

/// Bisection steps locating a crossing (the bracket shrinks below 1e-13
/// of its length, or of the value, first).
const BISECTIONS: usize = 60;

/// Everything a stability experiment computed.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StabilityResult {
    pub schema: String,
    pub experiment: String,
    /// The swept name (`init.v`).
    pub over: String,
    pub values: Vec<f64>,
    pub lines: Vec<Line>,
}

/// One formulation over the sweep.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Line {
    pub label: String,
    pub formulation: String,
    /// Essential components and cyclic coordinates (of the first value
    /// that linearised).
    pub essential: Vec<String>,
    pub cyclic: Vec<String>,
    /// Eigenvalues `[re, im]` at each value, by decreasing real part
    /// (empty where the linearisation failed).
    pub spectra: Vec<Vec<[f64; 2]>>,
    /// Why the linearisation failed at each value (`None`: it did not).
    pub errors: Vec<Option<String>>,
    pub crossings: Vec<Crossing>,
}

/// A value where the number of eigenvalues with positive real part changes.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct Crossing {
    pub value: f64,
    pub unstable_below: usize,
    pub unstable_above: usize,
    /// `real` (an eigenvalue through zero) or `complex pair` (a pair
    /// through the imaginary axis).
    pub mode: String,
    /// `|Im λ|` of the crossing eigenvalue (1/s): zero for a real one.
    pub frequency: f64,
    /// Why it could not be located (a linearisation failed inside the
    /// bracket); `value` is then the bracket's lower end.
    #[serde(default)]
    pub error: Option<String>,
}

/// Eigenvalues with real part above the zero level of [`ZERO`].
fn unstable(spectrum: &[[f64; 2]]) -> usize {
    let level = ZERO * scale(spectrum);
    spectrum.iter().filter(|z| z[0] > level).count()
}

/// The value of `over` as text at the `k`-th of `samples` evenly spread values.
pub fn sample(spec: &StabilitySpec, k: usize) -> f64 {
    let [a, b] = spec.range;
    if k + 1 == spec.samples {
        b
    } else {
        a + (b - a) * k as f64 / (spec.samples - 1) as f64
    }
}

/// One linearisation: its eigenvalues `[re, im]`, essential components
/// and cyclic coordinates.
type Sample = (Vec<[f64; 2]>, Vec<String>, Vec<String>);

/// `name=value` pairs, as the command line gives them.
type Pairs = Vec<(String, String)>;

/// The scene parameters and steady values of line `f` at `value` of `over`.
fn inputs(
    exp: &Experiment,
    spec: &StabilitySpec,
    f: &super::spec::FormulationSpec,
    value: f64,
) -> (Pairs, Pairs) {
    let (table, name) = spec.over.split_once('.').unwrap_or(("", ""));
    let set = [(name.to_string(), format!("{value:?}"))];
    let with = |base: &[(String, String)], own: &[(String, String)], here: bool| {
        let merged = override_with(base, own);
        if here {
            override_with(&merged, &set)
        } else {
            merged
        }
    };
    (
        with(&exp.params, &f.params, table == "param"),
        with(&exp.init, &f.init, table == "init"),
    )
}

/// Checks, when the file is read, that every line's steady state resolves
/// at both ends of the range (parameters in range, names known, no
/// velocities given twice); nothing is linearised.
pub fn check(exp: &Experiment) -> Result<(), String> {
    let Some(spec) = &exp.stability else {
        return Ok(());
    };
    for f in &exp.formulations {
        for value in spec.range {
            let (params, init) = inputs(exp, spec, f, value);
            let scene = nonholo_scenes::build(&exp.scene, &params)
                .map_err(|e| format!("{} at {} = {value}: {e}", f.label, spec.over))?;
            let model = crate::formulations::build_model(scene.clone(), &f.formulation, &f.options)
                .map_err(|e| format!("{}: {e}", f.label))?;
            let steady = crate::linearize::steady_pairs(scene.info(), &init);
            scene
                .visit(crate::simulate::ResolveInit {
                    given: steady,
                    extra: model.extra_init_names(),
                })
                .map_err(|e| format!("{} at {} = {value}: {e}", f.label, spec.over))?;
        }
    }
    Ok(())
}

/// The spectrum of line `f` of `exp` at `value` of `over`.
fn spectrum(
    exp: &Experiment,
    spec: &StabilitySpec,
    f: &super::spec::FormulationSpec,
    value: f64,
) -> Result<Sample, String> {
    let (params, init) = inputs(exp, spec, f, value);
    let opts = nonholo_stability::Options {
        independent: spec.independent.clone(),
        steady_tol: spec.steady_tol,
        ..nonholo_stability::Options::default()
    };
    let lin = linearise_at(
        &exp.scene,
        &params,
        &f.formulation,
        &f.options,
        &init,
        &opts,
    )
    .map_err(|e| e.to_string())?;
    let spectrum: Vec<[f64; 2]> = lin.modes.iter().map(|m| [m.value.re, m.value.im]).collect();
    if spectrum.iter().flatten().any(|v| !v.is_finite()) {
        return Err("the linearisation has eigenvalues that are not finite".into());
    }
    Ok((
        spectrum,
        lin.names,
        lin.cyclic.into_iter().map(|c| c.0).collect(),
    ))
}

/// The largest modulus of an eigenvalue, at least 1: the scale of [`ZERO`].
fn scale(spectrum: &[[f64; 2]]) -> f64 {
    spectrum
        .iter()
        .map(|z| z[0].hypot(z[1]))
        .fold(1.0, f64::max)
}

/// The `k`-th largest real part (and its eigenvalue) once the `zeros`
/// eigenvalues of smallest modulus — the structural zeros, found at the
/// ends of the bracket — are set aside: a continuous function of the
/// swept value whose sign change is the crossing.
fn ordered(spectrum: &[[f64; 2]], zeros: usize, k: usize) -> Option<[f64; 2]> {
    let mut s = spectrum.to_vec();
    s.sort_by(|a, b| a[0].hypot(a[1]).total_cmp(&b[0].hypot(b[1])));
    let mut rest = s.split_off(zeros.min(s.len()));
    rest.sort_by(|a, b| b[0].total_cmp(&a[0]));
    rest.get(k).copied()
}

/// Locates the crossing between `values` `(lo, hi)` with spectra `ends`,
/// where the unstable count changes from `below` to `above`: bisection on
/// the sign of the real part that changes sign ([`ordered`]), to 1e-13 of
/// the value, or on the count where that part does not change sign (two
/// modes crossing in one bracket).
fn locate(
    exp: &Experiment,
    spec: &StabilitySpec,
    f: &super::spec::FormulationSpec,
    (mut lo, mut hi): (f64, f64),
    ends: (&[[f64; 2]], &[[f64; 2]]),
    (below, above): (usize, usize),
) -> Result<Crossing, String> {
    let near_zero = |s: &[[f64; 2]]| {
        s.iter()
            .filter(|z| z[0].hypot(z[1]) <= ZERO * scale(s))
            .count()
    };
    let zeros = near_zero(ends.0).min(near_zero(ends.1));
    if near_zero(ends.0) != near_zero(ends.1) {
        // Eigenvalues leave zero at the end with more of them (C's ± pair
        // at v = 0): the crossing is that sample. A bisection towards it
        // would only find where the pair's size meets the rounding of the
        // repeated zero (about √ε).
        let value = if near_zero(ends.0) > near_zero(ends.1) {
            lo
        } else {
            hi
        };
        return Ok(Crossing {
            value,
            unstable_below: below,
            unstable_above: above,
            mode: "real".into(),
            frequency: 0.0,
            error: None,
        });
    }
    let k = below.min(above);
    let sign_at = |s: &[[f64; 2]]| ordered(s, zeros, k).map(|z| z[0] > 0.0);
    let by_part = match (sign_at(ends.0), sign_at(ends.1)) {
        (Some(a), Some(b)) => a != b,
        _ => false,
    };
    let start = if by_part { sign_at(ends.0) } else { None };
    let width = (hi - lo).abs();
    for _ in 0..BISECTIONS {
        if hi - lo <= 1e-13 * width.max(lo.abs().max(hi.abs())) {
            break;
        }
        let mid = 0.5 * (lo + hi);
        let (s, _, _) = spectrum(exp, spec, f, mid)?;
        let same = if by_part {
            sign_at(&s) == start
        } else {
            unstable(&s) == below
        };
        if same {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let value = 0.5 * (lo + hi);
    let (s, _, _) = spectrum(exp, spec, f, value)?;
    let crossing = ordered(&s, zeros, k).unwrap_or([0.0, 0.0]);
    let complex = crossing[1].abs() > 1e-6 * scale(&s);
    Ok(Crossing {
        value,
        unstable_below: below,
        unstable_above: above,
        mode: if complex { "complex pair" } else { "real" }.into(),
        frequency: if complex { crossing[1].abs() } else { 0.0 },
        error: None,
    })
}

/// Computes every line of `exp` on the threads of `pool`.
fn compute(
    exp: &Experiment,
    spec: &StabilitySpec,
    pool: &rayon::ThreadPool,
) -> Result<StabilityResult, String> {
    let values: Vec<f64> = (0..spec.samples).map(|k| sample(spec, k)).collect();
    let mut lines = Vec::new();
    for f in &exp.formulations {
        let results: Vec<_> = pool.install(|| {
            values
                .par_iter()
                .map(|&v| spectrum(exp, spec, f, v))
                .collect()
        });
        let essential = results
            .iter()
            .find_map(|r| r.as_ref().ok().map(|x| (x.1.clone(), x.2.clone())))
            .unwrap_or_default();
        let mut spectra = Vec::new();
        let mut errors = Vec::new();
        for r in results {
            match r {
                Ok((s, _, _)) => {
                    spectra.push(s);
                    errors.push(None);
                }
                Err(e) => {
                    spectra.push(Vec::new());
                    errors.push(Some(e));
                }
            }
        }
        let brackets: Vec<(usize, usize, usize)> = (0..values.len().saturating_sub(1))
            .filter(|&k| errors[k].is_none() && errors[k + 1].is_none())
            .map(|k| (k, unstable(&spectra[k]), unstable(&spectra[k + 1])))
            .filter(|&(_, a, b)| a != b)
            .collect();
        let crossings: Vec<Crossing> = pool.install(|| {
            brackets
                .par_iter()
                .map(|&(k, a, b)| {
                    let ends = (spectra[k].as_slice(), spectra[k + 1].as_slice());
                    locate(exp, spec, f, (values[k], values[k + 1]), ends, (a, b)).unwrap_or_else(
                        |e| Crossing {
                            value: values[k],
                            unstable_below: a,
                            unstable_above: b,
                            mode: "not located".into(),
                            frequency: 0.0,
                            error: Some(e),
                        },
                    )
                })
                .collect()
        });
        lines.push(Line {
            label: f.label.clone(),
            formulation: f.formulation.clone(),
            essential: essential.0,
            cyclic: essential.1,
            spectra,
            errors,
            crossings,
        });
    }
    Ok(StabilityResult {
        schema: SCHEMA.into(),
        experiment: exp.name.clone(),
        over: spec.over.clone(),
        values,
        lines,
    })
}

/// The stability spec of `exp` (present in every experiment of this kind).
fn spec_of(exp: &Experiment) -> Result<&StabilitySpec, CliError> {
    exp.stability
        .as_ref()
        .ok_or_else(|| CliError::Input(format!("{}: no [stability] table", exp.name)))
}

/// Runs a stability experiment and writes its results.
pub fn run(
    exp: &Experiment,
    opts: &RunOptions,
    out: super::ResultsDir,
) -> Result<Outcome, CliError> {
    let spec = spec_of(exp)?;
    let started = std::time::SystemTime::now();
    let dir = out.path().to_path_buf();
    out.prepare(&["plots"])?;
    let (pool, threads) = super::worker_pool(opts.threads)?;
    if !opts.quiet {
        crate::note!(
            "{}: {} formulation(s) linearised at {} values of {}",
            exp.name,
            exp.formulations.len(),
            spec.samples,
            spec.over
        );
    }
    let result = compute(exp, spec, &pool).map_err(CliError::Run)?;
    let written = (|| {
        write_json(&dir.join("stability.json"), &result)?;
        write_tables(&dir, &result)?;
        let plots = draw(exp, spec, &dir, &result)?;
        write_summary(exp, spec, &dir, &result)?;
        write_html(exp, &dir, &result, &plots)?;
        write_manifest(exp, &dir, started, threads)?;
        Ok::<_, String>(plots)
    })();
    let plots = written.map_err(CliError::Output)?;
    out.finish();
    let failed = result
        .lines
        .iter()
        .flat_map(|l| &l.errors)
        .filter(|e| e.is_some())
        .count();
    Ok(Outcome {
        dir,
        points: spec.samples,
        reused: 0,
        failed_runs: failed,
        stopped_runs: 0,
        budget_runs: 0,
        runs: spec.samples * exp.formulations.len(),
        failed_references: 0,
        plots,
    })
}

/// Redraws the figures and the page from `stability.json` (`nonholo plot`).
pub fn redraw(exp: &Experiment, out: super::ResultsDir) -> Result<Vec<PathBuf>, CliError> {
    let spec = spec_of(exp)?;
    let dir = out.path().to_path_buf();
    let path = dir.join("stability.json");
    let result: StabilityResult = super::read_stored(&dir, "stability.json")?;
    let current: Vec<f64> = (0..spec.samples).map(|k| sample(spec, k)).collect();
    let same_lines = result
        .lines
        .iter()
        .map(|l| (&l.label, &l.formulation))
        .eq(exp.formulations.iter().map(|f| (&f.label, &f.formulation)))
        && result
            .lines
            .iter()
            .all(|l| l.spectra.len() == current.len() && l.errors.len() == current.len());
    if result.schema != SCHEMA
        || result.over != spec.over
        || result.values != current
        || !same_lines
    {
        return Err(CliError::Input(format!(
            "{}: computed for another version of the experiment (run it again)",
            path.display()
        )));
    }
    let plots = (|| {
        let plots = draw(exp, spec, &dir, &result)?;
        write_html(exp, &dir, &result, &plots)?;
        Ok::<_, String>(plots)
    })()
    .map_err(CliError::Output)?;
    out.finish();
    Ok(plots)
}

fn write_tables(dir: &Path, r: &StabilityResult) -> Result<(), String> {
    let mut eig = Table::new(["label", "formulation", r.over.as_str(), "k", "re", "im"])?;
    let mut samples = Table::new([
        "label",
        "formulation",
        r.over.as_str(),
        "status",
        "unstable",
        "abscissa",
        "error",
    ])?;
    let mut cross = Table::new([
        "label",
        "formulation",
        r.over.as_str(),
        "unstable_below",
        "unstable_above",
        "mode",
        "frequency",
        "error",
    ])?;
    for l in &r.lines {
        for (k, v) in r.values.iter().enumerate() {
            for (i, z) in l.spectra[k].iter().enumerate() {
                eig.push(&(
                    &l.label,
                    &l.formulation,
                    table::Plain(*v),
                    i,
                    table::Plain(z[0]),
                    table::Plain(z[1]),
                ))?;
            }
            let abscissa = l.spectra[k]
                .iter()
                .map(|z| z[0])
                .reduce(f64::max)
                .map(table::Plain);
            match &l.errors[k] {
                None => samples.push(&(
                    &l.label,
                    &l.formulation,
                    table::Plain(*v),
                    "linearised",
                    unstable(&l.spectra[k]),
                    abscissa,
                    "",
                ))?,
                Some(e) => samples.push(&(
                    &l.label,
                    &l.formulation,
                    table::Plain(*v),
                    "failed",
                    "",
                    "",
                    e,
                ))?,
            }
        }
        for c in &l.crossings {
            cross.push(&(
                &l.label,
                &l.formulation,
                table::Plain(c.value),
                c.unstable_below,
                c.unstable_above,
                &c.mode,
                table::Plain(c.frequency),
                c.error.as_deref().unwrap_or(""),
            ))?;
        }
    }
    eig.write(&dir.join("eigenvalues.csv"))?;
    samples.write(&dir.join("samples.csv"))?;
    cross.write(&dir.join("crossings.csv"))
}

#[derive(Serialize)]
struct SummaryLine<'a> {
    label: &'a str,
    formulation: &'a str,
    essential: &'a [String],
    cyclic: &'a [String],
    failed: usize,
    crossings: &'a [Crossing],
}

#[derive(Serialize)]
struct Summary<'a> {
    schema: &'static str,
    name: &'a str,
    kind: &'static str,
    over: &'a str,
    range: [f64; 2],
    samples: usize,
    marks: Vec<(&'a str, f64)>,
    lines: Vec<SummaryLine<'a>>,
    plots: Vec<String>,
}

fn write_summary(
    exp: &Experiment,
    spec: &StabilitySpec,
    dir: &Path,
    r: &StabilityResult,
) -> Result<(), String> {
    let summary = Summary {
        schema: "nonholo.stability-summary/1",
        name: &exp.name,
        kind: "stability",
        over: &spec.over,
        range: spec.range,
        samples: spec.samples,
        marks: spec.marks.iter().map(|(n, v)| (n.as_str(), *v)).collect(),
        lines: r
            .lines
            .iter()
            .map(|l| SummaryLine {
                label: &l.label,
                formulation: &l.formulation,
                essential: &l.essential,
                cyclic: &l.cyclic,
                failed: l.errors.iter().filter(|e| e.is_some()).count(),
                crossings: &l.crossings,
            })
            .collect(),
        plots: vec!["eigenvalues-re".into(), "eigenvalues-im".into()],
    };
    write_json(&dir.join("summary.json"), &summary)
}

/// The axis label of the swept name: `name [unit]`.
fn swept_label(scene: &str, over: &str) -> String {
    match over.split_once('.') {
        Some(("param", name)) => {
            let unit = nonholo_scenes::info(scene)
                .ok()
                .and_then(|i| i.params.iter().find(|p| p.name == name).map(|p| p.unit))
                .filter(|u| !u.is_empty())
                .unwrap_or("–");
            format!("{name} [{unit}]")
        }
        Some((_, name)) => super::plots::quantity_label_in(nonholo_scenes::info(scene).ok(), name),
        None => format!("{over} [–]"),
    }
}

/// Real and imaginary parts against the swept value: each is drawn as the
/// k-th largest of its kind at every value (order statistics of continuous
/// functions are continuous, so the curves do not jump where eigenvalues
/// cross), one colour per formulation, with the marks as dotted verticals.
fn draw(
    exp: &Experiment,
    spec: &StabilitySpec,
    dir: &Path,
    r: &StabilityResult,
) -> Result<Vec<PathBuf>, String> {
    let pens = super::pens::of_experiment(exp);
    let x_label = swept_label(&exp.scene, &spec.over);
    let mut written = Vec::new();
    for (part, stem, what, fixed) in [
        (0, "eigenvalues-re", "Re λ [1/s]", spec.re_range),
        (1, "eigenvalues-im", "Im λ [1/s]", spec.im_range),
    ] {
        let mut series = Vec::new();
        let mut drawn = false;
        for l in &r.lines {
            let pen = super::pens::find(&pens, &l.label);
            let m = l.spectra.iter().map(Vec::len).max().unwrap_or(0);
            for k in 0..m {
                let y: Vec<f64> = l
                    .spectra
                    .iter()
                    .map(|s| {
                        let mut v: Vec<f64> = s.iter().map(|z| z[part]).collect();
                        v.sort_by(|a, b| b.total_cmp(a));
                        v.get(k).copied().unwrap_or(f64::NAN)
                    })
                    .collect();
                drawn |= y.iter().any(|v| v.is_finite());
                series.push(Series {
                    label: if k == 0 {
                        format!("{} ({})", l.label, l.formulation)
                    } else {
                        String::new()
                    },
                    x: r.values.clone(),
                    y,
                    pen,
                });
            }
        }
        let mut verticals = Vec::new();
        if drawn {
            // More points than a series gets dots for: a plain line.
            let n = 64;
            series.push(Series {
                label: String::new(),
                x: (0..n)
                    .map(|i| {
                        spec.range[0] + (spec.range[1] - spec.range[0]) * i as f64 / (n - 1) as f64
                    })
                    .collect(),
                y: vec![0.0; n],
                pen: Some(Pen {
                    colour: 6,
                    dash: Dash::Dotted,
                }),
            });
            verticals = spec
                .marks
                .iter()
                .map(|(name, v)| Vertical {
                    label: format!("{name} {v:.4}"),
                    x: *v,
                    pen: Pen {
                        colour: 6,
                        dash: Dash::Dashed,
                    },
                })
                .collect();
        }
        let title = format!(
            "{}: eigenvalues of the linearisation, {}",
            exp.scene,
            if part == 0 {
                "real parts"
            } else {
                "imaginary parts"
            }
        );
        written.extend(line_plot(
            &LinePlot {
                title,
                x_label: x_label.clone(),
                y_label: what.into(),
                series,
                verticals,
                y_range: fixed,
                ..LinePlot::default()
            },
            &dir.join("plots").join(stem),
        )?);
    }
    remove_other_figures(&dir.join("plots"), &written)?;
    Ok(written)
}

fn write_html(
    exp: &Experiment,
    dir: &Path,
    r: &StabilityResult,
    plots: &[PathBuf],
) -> Result<(), String> {
    let mut crossings = vec![
        [
            "line",
            r.over.as_str(),
            "unstable below",
            "unstable above",
            "mode",
            "frequency [1/s]",
        ]
        .map(String::from)
        .to_vec(),
    ];
    for l in &r.lines {
        for c in &l.crossings {
            crossings.push(vec![
                l.label.clone(),
                format!("{:.12}", c.value),
                c.unstable_below.to_string(),
                c.unstable_above.to_string(),
                c.mode.clone(),
                format!("{:.6}", c.frequency),
            ]);
        }
    }
    let mut reduced = vec![
        [
            "line",
            "essential components",
            "cyclic (quotiented out)",
            "failed samples",
        ]
        .map(String::from)
        .to_vec(),
    ];
    for l in &r.lines {
        reduced.push(vec![
            format!("{} ({})", l.label, l.formulation),
            l.essential.join(", "),
            l.cyclic.join(", "),
            l.errors.iter().filter(|e| e.is_some()).count().to_string(),
        ]);
    }
    let caption = |stem: &str| -> String {
        let part = if stem.ends_with("-im") {
            "Imaginary"
        } else {
            "Real"
        };
        format!(
            "{part} parts of the eigenvalues of each formulation's essential dynamics against {} \
             ({} evenly spread values); dashed verticals: published values; dotted: zero.",
            r.over,
            r.values.len()
        )
    };
    Page {
        exp,
        overview: String::new(),
        files: &[
            "crossings.csv",
            "samples.csv",
            "eigenvalues.csv",
            "stability.json",
            "summary.json",
            "manifest.json",
        ],
        before: vec![
            ("Where real parts cross zero".into(), table::html(crossings)),
            ("Reduction".into(), table::html(reduced)),
        ],
        plots,
        caption: &caption,
        after: Vec::new(),
    }
    .write(dir)
}
