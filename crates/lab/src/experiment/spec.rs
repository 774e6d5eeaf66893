//! Experiment files (the format for users: docs/experiments.md): the TOML
//! schema, and its validation into an [`Experiment`] whose every value has
//! been checked before anything runs.
//!
//! ```toml
//! [experiment]
//! name = "sleigh-slope-sweep"        # results go to results/<name>/
//! title = "…"
//! claim = "…"                        # the claim the figure tests
//! figure = true                      # part of `nonholo reproduce`
//! scene = "sleigh-incline"
//!
//! [params]                           # scene parameters
//! a = 0.4
//! [init]                             # initial values (names as for --init)
//! phi = 0.2
//!
//! [time]
//! t_end = 5.0
//! output_every = 0.01                # the common grid of every comparison
//!
//! [[formulation]]                    # one or more
//! label = "B"
//! formulation = "chetaev"            # or vakonomic, embedding, closed-form
//! integrator = "dop853"              # rtol, atol, step, max_steps, max_wall_time, project_init,
//!                                    # radau_newton = "auto" | "simplified" | "full",
//!                                    # radau_dense = "auto" | "collocation" | "hermite" (radau5's
//!                                    #   continuous extension; hermite: ODE formulations only;
//!                                    #   auto: hermite where there is one),
//!                                    # radau_jacobian_reuse = 0.1 (radau5 keeps its Jacobian
//!                                    #   after a Newton rate ≤ this; RADAU5's THET),
//!                                    # radau_newton_tol = 1e-6 (radau5's Newton stopping test,
//!                                    #   RADAU5's FNEWT; default its tolerance-dependent one),
//!                                    # stiff_stop = true (end where the stiffness test keeps firing)
//! options = { stab = "none" }
//! init = {}                          # formulation-specific initial values (lambda, x_ddot…)
//! params = {}                        # scene parameters overridden for this formulation
//!
//! [sweep]                            # optional
//! mode = "grid"                      # grid | zip | random
//! values = { "param.alpha" = [0.1, 0.3], "param.a" = [0.0, 0.4] }
//! # random: ranges = { "init.u" = [0.5, 3.0] }, samples = 20, seed = 1, log = ["…"]
//!
//! [measures]
//! threshold = 1e-6                   # divergence level whose first crossing is reported
//! reference = "B"                    # runs.csv reports divergence from this one
//! reversals = "u"                    # runs.csv counts its sign changes on the output grid
//!                                    # (a velocity-chart value, coordinate or `<coord>_dot`)
//! repeats = 5                        # timed runs of each formulation, median wall time (default 1)
//!
//! [plots]
//! point = 0                          # sweep point whose time series are drawn
//! also = [1]                         # further points drawn too (divergence-p1, …)
//! log_time = true                    # time axes of those figures logarithmic
//! divergence_from_reference = true   # divergence: each against the reference only
//! sweep_max = true                   # sweep figures: largest divergence, not the end value
//! main = "divergence"                # the figure shown for it in docs/figures.md
//! series = ["u"]                     # quantities drawn against time (series-<name>)
//! phase = ["u", "omega"]             # one against the other, every point with trajectories
//! series_span = [0.0, 5.0]           # their time window (default: the whole span)
//!
//! [work_precision]                   # experiments of kind = "work-precision" only
//! tolerances = [1e-4, 1e-6, 1e-8]    # rtol = atol ladder (steps = [...] for rk4); per line too
//! repeats = 5
//! reference = { integrator = "dopri5", rtol = 1e-13, check_integrator = "dop853",
//!               check_rtol = 3e-14, max_steps = 10000000, max_wall_time = 120 }
//! ```
//!
//! Every value is checked as the command line checks it (the same ranges
//! and reasons, [`crate::fields`]; docs/cli.md lists them), and a message
//! names the file, the line and the key. A sweep has at most
//! [`fields::MAX_SWEEP_POINTS`] points, counted before any is made.
//!
//! Budgets: `max_steps` stops a run at the same place on every machine;
//! `max_wall_time` does not, and a run it stops is recorded without its
//! time, counters and measures (see docs/schema.md) — figure experiments
//! use step budgets.
//!
//! Swept names: `param.<p>`, `init.<v>` (all formulations), `option.<o>`
//! (every formulation that has option `o`), `case` (a name for the point,
//! e.g. in a zip sweep over a catalogue of cases), and
//! `<label>.param.<p>`, `<label>.init.<v>`, `<label>.option.<o>`,
//! `<label>.rtol|atol|step|integrator|radau_newton|radau_dense|radau_jacobian_reuse|radau_newton_tol`
//! (one formulation).

use std::path::{Path, PathBuf};

use indexmap::IndexMap;
use nonholo_core::integrate::{Radau5Options, RadauDense};
use serde::Deserialize;
use toml::{Spanned, Value};

use super::sweep::Point;
use crate::fields;
use crate::formulations;
use crate::simulate::{DEFAULT_MAX_STEPS, DEFAULT_TOL};

type Entries = IndexMap<String, Spanned<Value>>;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    experiment: Header,
    #[serde(default)]
    params: Entries,
    #[serde(default)]
    init: Entries,
    time: Option<TimeFile>,
    #[serde(default, rename = "formulation")]
    formulations: Vec<FormulationFile>,
    sweep: Option<SweepFile>,
    #[serde(default)]
    measures: MeasuresFile,
    #[serde(default)]
    plots: PlotsFile,
    work_precision: Option<WorkPrecisionFile>,
    minimise: Option<MinimiseFile>,
    stability: Option<StabilityFile>,
    bvp: Option<BvpFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BvpFile {
    ends_from: Spanned<String>,
    h: Spanned<Vec<f64>>,
    horizons: Spanned<Vec<f64>>,
    #[serde(default)]
    stationarity: Vec<Spanned<String>>,
    #[serde(default)]
    stationarity_under: Vec<Spanned<String>>,
    start: Option<Spanned<String>>,
    tol: Option<Spanned<f64>>,
    max_iter: Option<Spanned<u64>>,
    #[serde(default, rename = "line")]
    lines: Vec<BvpLineFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct BvpLineFile {
    label: Spanned<String>,
    formulation: Spanned<String>,
    #[serde(default)]
    dependent: Vec<String>,
    ends: Option<Spanned<String>>,
    map_form: Option<Spanned<String>>,
}

/// `[bvp]` (experiments of kind `bvp`, docs/variational.md): at every point
/// of the sweep the `[[formulation]]` lines are integrated from `[init]` as
/// initial-value problems to the longest horizon; then, for every horizon
/// `t1` and grid spacing `h`, each `[[bvp.line]]` is solved as a
/// boundary-value problem on `[0, t1]` with the end data of line
/// `ends_from`, and compared with every initial-value line at the nodes; the
/// stationarity residual of the motions of the lines in `stationarity` is
/// measured under each boundary-value problem.
#[derive(Debug, Clone, PartialEq)]
pub struct BvpSpec {
    /// The `[[formulation]]` label whose motion gives the end data (and the
    /// starting path with `start = "reference"`).
    pub ends_from: String,
    /// Grid spacings, coarse to fine; every horizon is a whole number of
    /// each, and each a whole number of the finest.
    pub h: Vec<f64>,
    /// Horizons `t1`, increasing (the start is 0).
    pub horizons: Vec<f64>,
    /// `[[formulation]]` labels whose motions' stationarity is measured.
    pub stationarity: Vec<String>,
    /// The `[[bvp.line]]` labels under whose problems it is measured
    /// (default: every line).
    pub stationarity_under: Vec<String>,
    /// Start Newton from `ends_from`'s motion (`true`, `start =
    /// "reference"`, the default) or from the straight line between the
    /// ends (`start = "line"`).
    pub start_from_reference: bool,
    pub tol: f64,
    pub max_iter: usize,
    pub lines: Vec<BvpLine>,
}

/// One boundary-value formulation of a `bvp` experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct BvpLine {
    pub label: String,
    /// `vakonomic` or `embedding`.
    pub formulation: String,
    pub dependent: Vec<String>,
    pub ends: Option<String>,
    pub map_form: Option<String>,
    /// What these select on the experiment's scene.
    pub resolved: nonholo_variational::Formulation,
}

/// Most grid nodes of one boundary-value solve in an experiment.
pub const MAX_BVP_NODES: usize = 10_000_000;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct StabilityFile {
    over: Spanned<String>,
    range: Spanned<[f64; 2]>,
    samples: Spanned<u64>,
    #[serde(default)]
    independent: Vec<String>,
    #[serde(default)]
    marks: IndexMap<String, Spanned<f64>>,
    steady_tol: Option<Spanned<f64>>,
    re_range: Option<Spanned<[f64; 2]>>,
    im_range: Option<Spanned<[f64; 2]>>,
}

/// `[stability]` (experiments of kind `stability`): every formulation is
/// linearised about the steady motion of `[init]` (velocities not given
/// are zero) at `samples` values of one steady value or parameter `over`
/// (`init.<name>` or `param.<name>`) spread evenly over `range`; the
/// eigenvalues are drawn against it and the values where real parts cross
/// zero located (docs/stability.md).
#[derive(Debug, Clone, PartialEq)]
pub struct StabilitySpec {
    /// `init.v`, `param.c`, ...
    pub over: String,
    pub range: [f64; 2],
    pub samples: usize,
    /// State components kept independent where the constraints leave a choice.
    pub independent: Vec<String>,
    /// Published values of `over` drawn as vertical lines, with their names.
    pub marks: Vec<(String, f64)>,
    pub steady_tol: f64,
    /// Vertical ranges of the real-part and imaginary-part figures (1/s);
    /// default: fitted to every eigenvalue.
    pub re_range: Option<[f64; 2]>,
    pub im_range: Option<[f64; 2]>,
}

/// Most samples of a stability sweep.
pub const MAX_STABILITY_SAMPLES: usize = 10_000;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MinimiseFile {
    over: Spanned<String>,
    range: Spanned<[f64; 2]>,
    samples: Option<Spanned<u64>>,
    refine: Option<Spanned<u64>>,
    label: Spanned<String>,
}

/// `[minimise]` (compare experiments): at every point of the sweep, the
/// distance of one formulation from the reference at the end of their
/// common span is minimised over one more swept name (C's `λ(0)`, say) —
/// sampled on a uniform grid over `range`, then refined by golden-section
/// search in the brackets of the `refine` smallest sampled local minima.
#[derive(Debug, Clone, PartialEq)]
pub struct MinimiseSpec {
    /// The swept name varied (`C.init.lambda`).
    pub over: String,
    pub target: Target,
    pub range: [f64; 2],
    /// Grid samples over `range` (at least 3).
    pub samples: usize,
    /// Sampled local minima refined (0: the grid only).
    pub refine: usize,
    /// The formulation whose distance from the reference is minimised.
    pub label: String,
}

impl MinimiseSpec {
    /// `exp` with `over` as one more axis, and `point` of `exp` with `over`
    /// at `value`: what [`super::sweep::resolve`] turns into runs.
    pub fn at(&self, exp: &Experiment, point: &Point, value: f64) -> (Experiment, Point) {
        let mut e = exp.clone();
        e.axes.push(Axis {
            name: self.over.clone(),
            target: self.target.clone(),
            values: Vec::new(),
            line: 0,
        });
        let mut values = point.values.clone();
        values.push(format!("{value:e}"));
        (
            e,
            Point {
                index: point.index,
                values,
            },
        )
    }
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    name: Spanned<String>,
    title: String,
    claim: String,
    #[serde(default)]
    description: String,
    #[serde(default)]
    figure: bool,
    scene: Spanned<String>,
    /// `compare` (default) or `work-precision`.
    kind: Option<Spanned<String>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct TimeFile {
    t_end: Spanned<f64>,
    output_every: Spanned<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FormulationFile {
    label: Spanned<String>,
    formulation: Spanned<String>,
    integrator: Option<Spanned<String>>,
    rtol: Option<Spanned<f64>>,
    atol: Option<Spanned<f64>>,
    step: Option<Spanned<f64>>,
    max_steps: Option<Spanned<u64>>,
    max_wall_time: Option<Spanned<f64>>,
    radau_newton: Option<Spanned<String>>,
    radau_dense: Option<Spanned<String>>,
    radau_jacobian_reuse: Option<Spanned<f64>>,
    radau_newton_tol: Option<Spanned<f64>>,
    #[serde(default)]
    project_init: bool,
    #[serde(default)]
    stiff_stop: bool,
    #[serde(default)]
    options: Entries,
    #[serde(default)]
    init: Entries,
    #[serde(default)]
    params: Entries,
    /// Work-precision ladders and reference of this line (override `[work_precision]`).
    tolerances: Option<Spanned<Vec<f64>>>,
    steps: Option<Spanned<Vec<i64>>>,
    reference: Option<ReferenceFile>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WorkPrecisionFile {
    tolerances: Option<Spanned<Vec<f64>>>,
    steps: Option<Spanned<Vec<i64>>>,
    repeats: Option<Spanned<i64>>,
    reference: Option<ReferenceFile>,
}

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
struct ReferenceFile {
    integrator: Option<Spanned<String>>,
    rtol: Option<Spanned<f64>>,
    check_integrator: Option<Spanned<String>>,
    check_rtol: Option<Spanned<f64>>,
    max_wall_time: Option<Spanned<f64>>,
    max_steps: Option<Spanned<u64>>,
    closed_form: Option<bool>,
    #[serde(default)]
    options: Entries,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepFile {
    mode: Spanned<String>,
    #[serde(default)]
    values: IndexMap<String, Spanned<Vec<Spanned<Value>>>>,
    #[serde(default)]
    ranges: IndexMap<String, Spanned<Vec<f64>>>,
    #[serde(default)]
    log: Vec<String>,
    samples: Option<Spanned<u64>>,
    seed: Option<u64>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct MeasuresFile {
    threshold: Option<Spanned<f64>>,
    reference: Option<Spanned<String>>,
    reversals: Option<Spanned<String>>,
    repeats: Option<Spanned<i64>>,
}

#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlotsFile {
    point: Option<Spanned<u64>>,
    #[serde(default)]
    also: Vec<Spanned<u64>>,
    #[serde(default)]
    log_time: bool,
    #[serde(default)]
    divergence_from_reference: bool,
    #[serde(default)]
    sweep_max: bool,
    #[serde(default)]
    all_trajectories: bool,
    main: Option<String>,
    #[serde(default)]
    series: Vec<Spanned<String>>,
    series_span: Option<Spanned<[f64; 2]>>,
    #[serde(default)]
    phase: Vec<Spanned<String>>,
}

/// The pseudo-formulation that samples a scene's closed-form solution.
pub const CLOSED_FORM: &str = "closed-form";

/// Integration settings of one formulation.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    pub integrator: String,
    pub rtol: f64,
    pub atol: f64,
    pub step: Option<f64>,
    pub max_steps: usize,
    pub max_wall_time: Option<f64>,
    pub project_init: bool,
    /// Newton iteration of radau5: `auto`, `simplified`, `full`.
    pub radau_newton: String,
    /// Continuous extension of radau5: `auto`, `collocation`, `hermite`.
    pub radau_dense: String,
    /// radau5 keeps its Jacobian after a Newton contraction rate at most
    /// this (RADAU5's `THET`; negative: a new one every step).
    pub radau_jacobian_reuse: f64,
    /// radau5's Newton stopping test (RADAU5's `FNEWT`); `None`: its
    /// default, which depends on the tolerance.
    pub radau_newton_tol: Option<f64>,
    /// Stop an explicit run where its stiffness test keeps firing.
    pub stiff_stop: bool,
}

/// One formulation of an experiment, with everything given as text (the
/// same text the command line takes, parsed by the same code).
#[derive(Debug, Clone, PartialEq)]
pub struct FormulationSpec {
    pub label: String,
    pub formulation: String,
    pub settings: Settings,
    pub options: Vec<(String, String)>,
    pub init: Vec<(String, String)>,
    pub params: Vec<(String, String)>,
    /// Work-precision experiments: the ladder this line runs and its reference.
    pub work_precision: Option<(Ladder, RefSpec)>,
}

/// What an experiment does with its formulations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Run each formulation once per point and compare them (the default).
    Compare,
    /// Run each formulation over a ladder of tolerances (or step counts)
    /// and measure its error against a reference and its cost.
    WorkPrecision,
    /// Linearise each formulation about a steady motion over a range of
    /// one value (`[stability]`).
    Stability,
    /// Solve boundary-value problems with the ends of an initial-value run
    /// and compare (`[bvp]`).
    Bvp,
}

/// The work-precision ladder of one line.
#[derive(Debug, Clone, PartialEq)]
pub enum Ladder {
    /// `rtol = atol` values for adaptive methods.
    Tolerances(Vec<f64>),
    /// Numbers of equal steps over the span, for fixed-step methods.
    Steps(Vec<usize>),
}

/// How a work-precision line's reference is obtained: the scene's closed
/// form if it has one for this formulation (and `closed_form`), otherwise a
/// run with `integrator` at `rtol`, whose own error is estimated by a
/// second run with `check_integrator` at `check_rtol`.
#[derive(Debug, Clone, PartialEq)]
pub struct RefSpec {
    pub closed_form: bool,
    pub integrator: String,
    pub rtol: f64,
    pub check_integrator: String,
    pub check_rtol: f64,
    /// Wall-clock budget of each reference run, a safety net: where a run
    /// stops on it depends on the machine (such a stop is recorded as
    /// machine-dependent, see docs/schema.md).
    pub max_wall_time: Option<f64>,
    /// Step budget of each reference run (the same on every machine).
    pub max_steps: usize,
    /// Formulation options of the reference runs over the line's own (e.g.
    /// the direct form of `mass` measured against its compliance form: the
    /// same motion, without the direct form's ill-conditioning).
    pub options: Vec<(String, String)>,
}

impl RefSpec {
    /// The default reference of formulation `name`: DOPRI5 at 1e-13 checked
    /// by DOP853 at 3e-14 — measured on the sleigh's closed form over 20 s,
    /// 7e-13 and 3e-12 at most on the grid. A: its explicit form by DOP853
    /// at 1e-13, checked by DOPRI5 at 1e-13 (its implicit form by Radau IIA
    /// cannot go below ~1e-10).
    pub fn default_for(name: &str) -> RefSpec {
        if name == nonholo_embedding::INFO.name {
            RefSpec {
                closed_form: true,
                integrator: "dop853".into(),
                rtol: 1e-13,
                check_integrator: "dopri5".into(),
                check_rtol: 1e-13,
                max_wall_time: Some(120.0),
                max_steps: DEFAULT_MAX_STEPS,
                options: Vec::new(),
            }
        } else {
            RefSpec {
                closed_form: true,
                integrator: "dopri5".into(),
                rtol: 1e-13,
                check_integrator: "dop853".into(),
                check_rtol: 3e-14,
                max_wall_time: Some(120.0),
                max_steps: DEFAULT_MAX_STEPS,
                options: Vec::new(),
            }
        }
    }
}

/// What a swept name addresses.
#[derive(Debug, Clone, PartialEq)]
pub enum Target {
    Param(String),
    Init(String),
    /// An option of every formulation that has it (`option.k`).
    Option(String),
    /// The name of a case in a catalogue (`case`): labels the point only.
    Case,
    FormParam(String, String),
    FormInit(String, String),
    FormOption(String, String),
    FormSetting(String, String),
}

/// One swept variable and its values (as text).
#[derive(Debug, Clone, PartialEq)]
pub struct Axis {
    pub name: String,
    pub target: Target,
    pub values: Vec<String>,
    /// Line of the axis in the experiment file (0 if built in code).
    pub line: usize,
}

/// How the axes combine into points.
#[derive(Debug, Clone, PartialEq)]
pub enum SweepMode {
    /// No sweep: a single point.
    Single,
    /// Every combination, the first axis varying slowest.
    Grid,
    /// The i-th values of every axis together.
    Zip,
    /// `samples` points drawn uniformly (log-uniformly for `log` axes) from
    /// `[lo, hi]` with a seeded generator; axis values hold `lo`, `hi`.
    Random {
        samples: usize,
        seed: u64,
        log: Vec<String>,
    },
}

/// A validated experiment.
#[derive(Debug, Clone)]
pub struct Experiment {
    pub name: String,
    pub title: String,
    pub claim: String,
    pub description: String,
    pub figure: bool,
    pub path: PathBuf,
    pub source: String,
    pub scene: String,
    pub params: Vec<(String, String)>,
    pub init: Vec<(String, String)>,
    pub t_end: f64,
    pub output_every: f64,
    pub formulations: Vec<FormulationSpec>,
    pub mode: SweepMode,
    pub axes: Vec<Axis>,
    pub threshold: f64,
    pub reference: String,
    /// The quantity whose sign changes on the output grid `runs.csv`
    /// counts (`reversals`): a velocity-chart value, coordinate or velocity.
    pub reversals: Option<String>,
    pub plot_point: usize,
    /// Further points whose time series are drawn too (`<figure>-p<i>`).
    pub also_points: Vec<usize>,
    /// Time axes of the time-series figures drawn logarithmically.
    pub log_time: bool,
    /// The divergence figure shows each formulation against the reference
    /// only (by default every pair, up to four formulations).
    pub divergence_from_reference: bool,
    /// Figures over the sweep show the largest divergence over the common
    /// span instead of the divergence at its end.
    pub sweep_max: bool,
    pub all_trajectories: bool,
    /// The plot that stands for the experiment in docs/figures.md (file stem).
    pub main_plot: Option<String>,
    /// Quantities drawn against time for every formulation (`series-<name>`),
    /// over `series_span` (default: the whole span).
    pub series: Vec<String>,
    pub series_span: Option<[f64; 2]>,
    /// Two quantities drawn against each other for every point with
    /// trajectories (`phase`): a phase portrait, one colour per formulation.
    pub phase: Option<[String; 2]>,
    pub kind: Kind,
    /// A minimisation over one more swept name at every point.
    pub minimise: Option<MinimiseSpec>,
    /// What a stability experiment sweeps (kind `stability` only).
    pub stability: Option<StabilitySpec>,
    /// The boundary-value problems of a `bvp` experiment.
    pub bvp: Option<BvpSpec>,
    /// Timed repeats of every run, the median wall time reported
    /// (work-precision: `[work_precision] repeats`, default 5; compare:
    /// `[measures] repeats`, default 1).
    pub repeats: usize,
}

impl Experiment {
    /// The description of the experiment's scene with its `[params]`
    /// (the coordinates of `sleigh-train` depend on its `N`; the
    /// parameters that do cannot be swept, so every point shares it).
    pub fn scene_info(&self) -> Result<&'static nonholo_core::SceneInfo, String> {
        nonholo_scenes::describe(&self.scene, &self.params).map_err(|e| e.to_string())
    }
}

/// An error in an experiment file, naming the file, line and key.
#[derive(Debug, Clone, PartialEq)]
pub struct SpecError(pub String);

impl std::fmt::Display for SpecError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

struct Ctx<'a> {
    path: &'a Path,
    source: &'a str,
}

impl Ctx<'_> {
    fn line(&self, offset: usize) -> usize {
        self.source[..offset.min(self.source.len())]
            .bytes()
            .filter(|&b| b == b'\n')
            .count()
            + 1
    }

    fn err(
        &self,
        span: std::ops::Range<usize>,
        key: &str,
        msg: impl std::fmt::Display,
    ) -> SpecError {
        SpecError(format!(
            "{}:{}: `{key}`: {msg}",
            self.path.display(),
            self.line(span.start)
        ))
    }
}

/// Longest experiment name or formulation label (each names files).
pub const MAX_NAME: usize = 64;

/// A formulation label names files (`trajectories/<i>-<label>.csv`) and
/// fills a text column of the tables: a letter, then letters, digits, `-`
/// and `_`, at most [`MAX_NAME`]; never a word a CSV reader takes for a
/// number (`nan`, `inf`).
fn check_label(label: &str) -> Result<(), String> {
    let mut chars = label.chars();
    let shape = chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        && label.len() <= MAX_NAME;
    let numeric = ["nan", "inf", "infinity"]
        .iter()
        .any(|w| label.eq_ignore_ascii_case(w));
    if shape && !numeric {
        Ok(())
    } else {
        Err(format!(
            "`{label}`: a label is a letter followed by letters, digits, `-` and `_` (at most \
             {MAX_NAME}; not `nan` or `inf`): it names files and fills a column of the tables"
        ))
    }
}

/// The text of a TOML value as the command line would give it.
fn text(v: &Value) -> Result<String, String> {
    match v {
        Value::String(s) => Ok(s.clone()),
        Value::Integer(i) => Ok(i.to_string()),
        Value::Float(f) => Ok(format!("{f:?}")),
        Value::Boolean(b) => Ok(b.to_string()),
        other => Err(format!(
            "expected a number or a string, found {}",
            other.type_str()
        )),
    }
}

fn entries(ctx: &Ctx, table: &str, e: &Entries) -> Result<Vec<(String, String)>, SpecError> {
    e.iter()
        .map(|(k, v)| {
            text(v.get_ref())
                .map(|t| (k.clone(), t))
                .map_err(|m| ctx.err(v.span(), &format!("{table}.{k}"), m))
        })
        .collect()
}

pub(crate) fn override_with(
    base: &[(String, String)],
    extra: &[(String, String)],
) -> Vec<(String, String)> {
    let mut out: Vec<(String, String)> = base
        .iter()
        .filter(|(k, _)| !extra.iter().any(|(e, _)| e == k))
        .cloned()
        .collect();
    out.extend(extra.iter().cloned());
    out
}

/// `t`, unless it varies a parameter that changes the scene's coordinates
/// ([`nonholo_scenes::structural`]): every point of an experiment has the
/// same coordinates.
fn fixed_size(scene: &str, t: Target) -> Result<Target, String> {
    let p = match &t {
        Target::Param(p) | Target::FormParam(_, p) => p,
        _ => return Ok(t),
    };
    if nonholo_scenes::structural(scene).contains(&p.as_str()) {
        return Err(format!(
            "`{p}` sets the size of scene `{scene}` (its coordinates): it cannot vary within one \
             experiment; set it in [params] and write one experiment per value"
        ));
    }
    Ok(t)
}

fn parse_target(name: &str, labels: &[String]) -> Result<Target, String> {
    let parts: Vec<&str> = name.split('.').collect();
    let bad = || {
        format!(
            "cannot address `{name}`: use param.<p>, init.<v>, option.<o>, case, or <label>.param.<p>, \
             <label>.init.<v>, <label>.option.<o>, <label>.rtol|atol|step|integrator|radau_newton|radau_dense|radau_jacobian_reuse|radau_newton_tol \
             (labels: {})",
            labels.join(", ")
        )
    };
    match parts.as_slice() {
        ["param", p] => Ok(Target::Param(p.to_string())),
        ["init", v] => Ok(Target::Init(v.to_string())),
        ["option", o] => Ok(Target::Option(o.to_string())),
        ["case"] => Ok(Target::Case),
        [label, kind, key] if labels.iter().any(|l| l == label) => match *kind {
            "param" => Ok(Target::FormParam(label.to_string(), key.to_string())),
            "init" => Ok(Target::FormInit(label.to_string(), key.to_string())),
            "option" => Ok(Target::FormOption(label.to_string(), key.to_string())),
            _ => Err(bad()),
        },
        [label, setting] if labels.iter().any(|l| l == label) => match *setting {
            "rtol"
            | "atol"
            | "step"
            | "integrator"
            | "radau_newton"
            | "radau_dense"
            | "radau_jacobian_reuse"
            | "radau_newton_tol" => Ok(Target::FormSetting(label.to_string(), setting.to_string())),
            _ => Err(bad()),
        },
        _ => Err(bad()),
    }
}

/// Applies one swept value to the formulation specs.
pub fn apply(
    target: &Target,
    value: &str,
    scene_params: &mut Vec<(String, String)>,
    forms: &mut [FormulationSpec],
    init: &mut Vec<(String, String)>,
) -> Result<(), String> {
    let set = |list: &mut Vec<(String, String)>, k: &str| {
        *list = override_with(list, &[(k.to_string(), value.to_string())]);
    };
    match target {
        Target::Param(p) => set(scene_params, p),
        Target::Init(v) => set(init, v),
        Target::Case => {}
        Target::Option(o) => {
            let mut any = false;
            for f in forms.iter_mut() {
                let has = formulations::info(&f.formulation)
                    .is_ok_and(|info| info.options.iter().any(|spec| spec.name == o));
                if has {
                    set(&mut f.options, o);
                    any = true;
                }
            }
            if !any {
                return Err(format!(
                    "no formulation of the experiment has an option `{o}`"
                ));
            }
        }
        Target::FormParam(l, p)
        | Target::FormInit(l, p)
        | Target::FormOption(l, p)
        | Target::FormSetting(l, p) => {
            let f = forms
                .iter_mut()
                .find(|f| &f.label == l)
                .ok_or_else(|| format!("no formulation labelled `{l}`"))?;
            match target {
                Target::FormParam(..) => set(&mut f.params, p),
                Target::FormInit(..) => set(&mut f.init, p),
                Target::FormOption(..) => set(&mut f.options, p),
                _ => {
                    let field = format!("{l}.{p}");
                    let num = |check: fn(f64) -> Result<f64, String>| {
                        value
                            .parse::<f64>()
                            .map_err(|_| format!("`{field}`: `{value}` is not a number"))
                            .and_then(|v| check(v).map_err(|m| format!("`{field}`: {m}")))
                    };
                    match p.as_str() {
                        "rtol" => f.settings.rtol = num(fields::rtol)?,
                        "atol" => f.settings.atol = num(fields::atol)?,
                        "step" => f.settings.step = Some(num(fields::step)?),
                        "radau_newton" => {
                            fields::radau_newton(value).map_err(|m| format!("`{field}`: {m}"))?;
                            f.settings.radau_newton = value.to_string();
                        }
                        "radau_dense" => {
                            fields::radau_dense(value).map_err(|m| format!("`{field}`: {m}"))?;
                            f.settings.radau_dense = value.to_string();
                        }
                        "radau_jacobian_reuse" => {
                            f.settings.radau_jacobian_reuse = num(fields::radau_jacobian_reuse)?
                        }
                        "radau_newton_tol" => {
                            f.settings.radau_newton_tol = Some(num(fields::radau_newton_tol)?)
                        }
                        _ => {
                            fields::method(value).map_err(|m| format!("`{field}`: {m}"))?;
                            f.settings.integrator = value.to_string();
                        }
                    }
                }
            }
        }
    }
    Ok(())
}

impl Experiment {
    /// Reads and validates `path`.
    pub fn load(path: &Path) -> Result<Experiment, SpecError> {
        let source = std::fs::read_to_string(path)
            .map_err(|e| SpecError(format!("cannot read {}: {e}", path.display())))?;
        Experiment::parse(path, &source)
    }

    /// Parses and validates the text of an experiment file.
    pub fn parse(path: &Path, source: &str) -> Result<Experiment, SpecError> {
        let file: File =
            toml::from_str(source).map_err(|e| SpecError(format!("{}: {e}", path.display())))?;
        let ctx = Ctx { path, source };

        let name = file.experiment.name.get_ref().clone();
        if name.is_empty()
            || name.len() > MAX_NAME
            || !name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(ctx.err(
                file.experiment.name.span(),
                "experiment.name",
                format!(
                    "must be a name of 1 to {MAX_NAME} letters, digits, `-` and `_` (it names \
                     the results directory)"
                ),
            ));
        }

        let scene = file.experiment.scene.get_ref().clone();
        nonholo_scenes::info(&scene)
            .map_err(|e| ctx.err(file.experiment.scene.span(), "experiment.scene", e))?;
        let params = entries(&ctx, "params", &file.params)?;
        let init = entries(&ctx, "init", &file.init)?;

        let stability_kind = file
            .experiment
            .kind
            .as_ref()
            .is_some_and(|k| k.get_ref() == "stability");
        let bvp_kind = file
            .experiment
            .kind
            .as_ref()
            .is_some_and(|k| k.get_ref() == "bvp");
        let (t_end, every) = match &file.time {
            Some(time) if bvp_kind => {
                return Err(ctx.err(
                    time.t_end.span(),
                    "time",
                    "a bvp experiment's spans are its [bvp] horizons and its grids [bvp] h",
                ));
            }
            None if bvp_kind => bvp_span(&ctx, &file)?,
            Some(time) => {
                let t_end = fields::t_end(*time.t_end.get_ref())
                    .map_err(|m| ctx.err(time.t_end.span(), "time.t_end", m))?;
                let every = fields::output_every(*time.output_every.get_ref(), t_end)
                    .map_err(|m| ctx.err(time.output_every.span(), "time.output_every", m))?;
                (t_end, every)
            }
            // A linearisation has no time span.
            None if stability_kind => (1.0, 1.0),
            None => {
                return Err(SpecError(format!(
                    "{}: missing table [time] (t_end, output_every)",
                    path.display()
                )));
            }
        };

        if file.formulations.is_empty() {
            return Err(SpecError(format!(
                "{}: no [[formulation]]: an experiment compares at least one formulation",
                path.display()
            )));
        }
        let mut forms = Vec::new();
        for f in &file.formulations {
            let label = f.label.get_ref().clone();
            if forms.iter().any(|g: &FormulationSpec| g.label == label) {
                return Err(ctx.err(
                    f.label.span(),
                    "formulation.label",
                    format!("`{label}` used twice"),
                ));
            }
            check_label(&label).map_err(|m| ctx.err(f.label.span(), "formulation.label", m))?;
            let name = f.formulation.get_ref().clone();
            if name != CLOSED_FORM {
                formulations::info(&name)
                    .map_err(|e| ctx.err(f.formulation.span(), "formulation.formulation", e))?;
            }
            let default_integrator = if name == nonholo_embedding::INFO.name {
                "radau5"
            } else {
                "dop853"
            };
            let integrator = f
                .integrator
                .as_ref()
                .map(|s| s.get_ref().clone())
                .unwrap_or_else(|| default_integrator.to_string());
            let method = if name == CLOSED_FORM {
                None
            } else {
                let span = f
                    .integrator
                    .as_ref()
                    .map(|s| s.span())
                    .unwrap_or(f.label.span());
                Some(
                    fields::method(&integrator)
                        .map_err(|m| ctx.err(span, "formulation.integrator", m))?,
                )
            };
            // The checks of the command line (`fields`), named by key and line.
            fn checked<T: Copy, U>(
                ctx: &Ctx,
                v: &Option<Spanned<T>>,
                key: &str,
                check: impl Fn(T) -> Result<U, String>,
            ) -> Result<Option<U>, SpecError> {
                v.as_ref()
                    .map(|s| check(*s.get_ref()).map_err(|m| ctx.err(s.span(), key, m)))
                    .transpose()
            }
            let step = checked(&ctx, &f.step, "formulation.step", fields::step)?;
            if let (Some(_), Some(method)) = (step, method) {
                for (given, key) in [(&f.rtol, "formulation.rtol"), (&f.atol, "formulation.atol")] {
                    if let Some(v) = given {
                        fields::tolerance_with_step(method, "`step`")
                            .map_err(|m| ctx.err(v.span(), key, m))?;
                    }
                }
            }
            forms.push(FormulationSpec {
                label,
                formulation: name,
                settings: Settings {
                    integrator,
                    rtol: checked(&ctx, &f.rtol, "formulation.rtol", fields::rtol)?
                        .unwrap_or(DEFAULT_TOL),
                    atol: checked(&ctx, &f.atol, "formulation.atol", fields::atol)?
                        .unwrap_or(DEFAULT_TOL),
                    step,
                    max_steps: checked(
                        &ctx,
                        &f.max_steps,
                        "formulation.max_steps",
                        fields::max_steps,
                    )?
                    .unwrap_or(DEFAULT_MAX_STEPS),
                    max_wall_time: checked(
                        &ctx,
                        &f.max_wall_time,
                        "formulation.max_wall_time",
                        fields::max_wall_time,
                    )?,
                    project_init: f.project_init,
                    radau_newton: match &f.radau_newton {
                        None => "auto".into(),
                        Some(v) => {
                            fields::radau_newton(v.get_ref())
                                .map_err(|m| ctx.err(v.span(), "formulation.radau_newton", m))?;
                            v.get_ref().clone()
                        }
                    },
                    radau_dense: match &f.radau_dense {
                        None => RadauDense::default().name().into(),
                        Some(v) => {
                            fields::radau_dense(v.get_ref())
                                .map_err(|m| ctx.err(v.span(), "formulation.radau_dense", m))?;
                            v.get_ref().clone()
                        }
                    },
                    radau_jacobian_reuse: checked(
                        &ctx,
                        &f.radau_jacobian_reuse,
                        "formulation.radau_jacobian_reuse",
                        fields::radau_jacobian_reuse,
                    )?
                    .unwrap_or(Radau5Options::default().jacobian_reuse),
                    radau_newton_tol: checked(
                        &ctx,
                        &f.radau_newton_tol,
                        "formulation.radau_newton_tol",
                        fields::radau_newton_tol,
                    )?,
                    stiff_stop: f.stiff_stop,
                },
                options: entries(&ctx, "formulation.options", &f.options)?,
                init: entries(&ctx, "formulation.init", &f.init)?,
                params: {
                    let own = entries(&ctx, "formulation.params", &f.params)?;
                    if let Some((k, v)) = f
                        .params
                        .iter()
                        .find(|(k, _)| nonholo_scenes::structural(&scene).contains(&k.as_str()))
                    {
                        return Err(ctx.err(
                            v.span(),
                            &format!("formulation.params.{k}"),
                            format!(
                                "`{k}` sets the size of scene `{scene}` (its coordinates): every \
                                 formulation of an experiment shares it; set it in [params]"
                            ),
                        ));
                    }
                    own
                },
                work_precision: None,
            });
        }
        let kind = match &file.experiment.kind {
            None => Kind::Compare,
            Some(k) => match k.get_ref().as_str() {
                "compare" => Kind::Compare,
                "work-precision" => Kind::WorkPrecision,
                "stability" => Kind::Stability,
                "bvp" => Kind::Bvp,
                other => {
                    return Err(ctx.err(
                        k.span(),
                        "experiment.kind",
                        format!(
                            "unknown kind `{other}`; valid: compare, work-precision, stability, \
                             bvp"
                        ),
                    ));
                }
            },
        };
        let repeats = work_precision_lines(&ctx, kind, &file, &mut forms, t_end)?;
        let stability = stability(&ctx, kind, &file)?;
        let bvp = bvp(&ctx, kind, &file, &forms)?;
        let labels: Vec<String> = forms.iter().map(|f| f.label.clone()).collect();

        let (mode, axes) = match &file.sweep {
            None => (SweepMode::Single, Vec::new()),
            Some(sw) => {
                let mut axes = Vec::new();
                let mode = match sw.mode.get_ref().as_str() {
                    m @ ("grid" | "zip") => {
                        if sw.values.is_empty() {
                            return Err(ctx.err(
                                sw.mode.span(),
                                "sweep.values",
                                "a grid or zip sweep needs at least one swept name with values",
                            ));
                        }
                        if !sw.ranges.is_empty() {
                            return Err(ctx.err(
                                sw.mode.span(),
                                "sweep.ranges",
                                "ranges belong to random sweeps",
                            ));
                        }
                        for (k, vals) in &sw.values {
                            let target = parse_target(k, &labels)
                                .and_then(|t| fixed_size(&scene, t))
                                .map_err(|m| {
                                    ctx.err(vals.span(), &format!("sweep.values.{k}"), m)
                                })?;
                            if vals.get_ref().is_empty() {
                                return Err(ctx.err(
                                    vals.span(),
                                    &format!("sweep.values.{k}"),
                                    "empty list: nothing to sweep",
                                ));
                            }
                            let values = vals
                                .get_ref()
                                .iter()
                                .map(|v| {
                                    text(v.get_ref())
                                        .and_then(|t| {
                                            if t.parse::<f64>().is_ok_and(|x| !x.is_finite()) {
                                                Err(format!(
                                                    "`{t}` is not a finite number (a swept value \
                                                     fills a column of the tables)"
                                                ))
                                            } else {
                                                Ok(t)
                                            }
                                        })
                                        .map_err(|m| {
                                            ctx.err(v.span(), &format!("sweep.values.{k}"), m)
                                        })
                                })
                                .collect::<Result<Vec<_>, _>>()?;
                            axes.push(Axis {
                                name: k.clone(),
                                target,
                                values,
                                line: ctx.line(vals.span().start),
                            });
                        }
                        if m == "zip" {
                            let n = axes[0].values.len();
                            if let Some(a) = axes.iter().find(|a| a.values.len() != n) {
                                let span = sw.values[&a.name].span();
                                return Err(ctx.err(span, &format!("sweep.values.{}", a.name), format!(
                                    "a zip sweep needs lists of equal length ({} has {}, {} has {n})",
                                    a.name, a.values.len(), axes[0].name
                                )));
                            }
                        }
                        // Counted before any point is made: a grid's size is
                        // the product of its axes' lengths.
                        let count = if m == "zip" {
                            Some(axes[0].values.len() as u64)
                        } else {
                            axes.iter()
                                .try_fold(1u64, |n, a| n.checked_mul(a.values.len() as u64))
                        };
                        fields::sweep_points(count)
                            .map_err(|e| ctx.err(sw.mode.span(), "sweep.values", e))?;
                        if m == "zip" {
                            SweepMode::Zip
                        } else {
                            SweepMode::Grid
                        }
                    }
                    "random" => {
                        if sw.ranges.is_empty() {
                            return Err(ctx.err(
                                sw.mode.span(),
                                "sweep.ranges",
                                "a random sweep needs ranges = { name = [lo, hi] }",
                            ));
                        }
                        let samples = match &sw.samples {
                            None => {
                                return Err(ctx.err(
                                    sw.mode.span(),
                                    "sweep.samples",
                                    "a random sweep needs samples ≥ 1",
                                ));
                            }
                            Some(s) => fields::sweep_points(Some(*s.get_ref()))
                                .map_err(|e| ctx.err(s.span(), "sweep.samples", e))?,
                        };
                        for (k, r) in &sw.ranges {
                            let target = parse_target(k, &labels)
                                .and_then(|t| fixed_size(&scene, t))
                                .map_err(|m| ctx.err(r.span(), &format!("sweep.ranges.{k}"), m))?;
                            let v = r.get_ref();
                            let log = sw.log.contains(k);
                            if v.len() != 2
                                || !(v[0].is_finite() && v[1].is_finite() && v[0] < v[1])
                                || !(v[1] - v[0]).is_finite()
                                || (log && v[0] <= 0.0)
                            {
                                return Err(ctx.err(r.span(), &format!("sweep.ranges.{k}"), "must be [lo, hi] with finite lo < hi, a finite width hi − lo (and lo > 0 on a log axis)"));
                            }
                            axes.push(Axis {
                                name: k.clone(),
                                target,
                                values: vec![format!("{:?}", v[0]), format!("{:?}", v[1])],
                                line: ctx.line(r.span().start),
                            });
                        }
                        if let Some(l) = sw.log.iter().find(|l| !sw.ranges.contains_key(*l)) {
                            return Err(ctx.err(
                                sw.mode.span(),
                                "sweep.log",
                                format!("`{l}` is not one of the ranges"),
                            ));
                        }
                        SweepMode::Random {
                            samples,
                            seed: sw.seed.unwrap_or(0),
                            log: sw.log.clone(),
                        }
                    }
                    other => {
                        return Err(ctx.err(
                            sw.mode.span(),
                            "sweep.mode",
                            format!("unknown mode `{other}`; valid: grid, zip, random"),
                        ));
                    }
                };
                (mode, axes)
            }
        };

        let threshold = match &file.measures.threshold {
            None => 1e-6,
            Some(t) if t.get_ref().is_finite() && *t.get_ref() > 0.0 => *t.get_ref(),
            Some(t) => {
                return Err(ctx.err(
                    t.span(),
                    "measures.threshold",
                    "must be a positive finite number",
                ));
            }
        };
        let reference = match &file.measures.reference {
            None => labels[0].clone(),
            Some(r) if labels.contains(r.get_ref()) => r.get_ref().clone(),
            Some(r) => {
                return Err(ctx.err(
                    r.span(),
                    "measures.reference",
                    format!(
                        "no formulation labelled `{}`; labels: {}",
                        r.get_ref(),
                        labels.join(", ")
                    ),
                ));
            }
        };

        // Quantities a measure or a plot may name: the velocity-chart
        // values, coordinates and velocities of the scene.
        let quantities: Vec<String> = nonholo_scenes::describe(&scene, &params)
            .map(|i| {
                i.velocity_chart
                    .iter()
                    .map(|c| c.name.to_string())
                    .chain(i.coordinates.iter().map(|c| c.name.to_string()))
                    .chain(i.coordinates.iter().map(|c| format!("{}_dot", c.name)))
                    .collect()
            })
            .unwrap_or_default();
        let quantity = |q: &Spanned<String>, key: &str| -> Result<String, SpecError> {
            if quantities.contains(q.get_ref()) {
                Ok(q.get_ref().clone())
            } else {
                Err(ctx.err(
                    q.span(),
                    key,
                    format!(
                        "scene `{scene}` has no quantity `{}`; valid: {}",
                        q.get_ref(),
                        quantities.join(", ")
                    ),
                ))
            }
        };
        let reversals = file
            .measures
            .reversals
            .as_ref()
            .map(|q| quantity(q, "measures.reversals"))
            .transpose()?;
        let mut series = file
            .plots
            .series
            .iter()
            .map(|q| quantity(q, "plots.series"))
            .collect::<Result<Vec<_>, _>>()?;
        let phase = match file.plots.phase.as_slice() {
            [] => None,
            [a, b] => {
                let pair = [quantity(a, "plots.phase")?, quantity(b, "plots.phase")?];
                // The trajectories carry the pair's columns as they carry a series'.
                for q in &pair {
                    if !series.contains(q) {
                        series.push(q.clone());
                    }
                }
                Some(pair)
            }
            more => {
                let span = more[0].span().start..more[more.len() - 1].span().end;
                return Err(ctx.err(
                    span,
                    "plots.phase",
                    "must name two quantities: the horizontal and the vertical axis",
                ));
            }
        };
        let series_span = match &file.plots.series_span {
            None => None,
            Some(s) => {
                let [a, b] = *s.get_ref();
                if !(a.is_finite() && b.is_finite() && a >= 0.0 && a < b && a < t_end) {
                    return Err(ctx.err(
                        s.span(),
                        "plots.series_span",
                        format!(
                            "must be [start, end] with 0 ≤ start < end and start < t_end = {t_end}"
                        ),
                    ));
                }
                Some([a, b])
            }
        };

        let exp = Experiment {
            name,
            title: file.experiment.title.clone(),
            claim: file.experiment.claim.clone(),
            description: file.experiment.description.clone(),
            figure: file.experiment.figure,
            path: path.to_path_buf(),
            source: source.to_string(),
            scene,
            params,
            init,
            t_end,
            output_every: every,
            formulations: forms,
            mode,
            axes,
            threshold,
            reference,
            reversals,
            plot_point: file
                .plots
                .point
                .as_ref()
                .map(|p| *p.get_ref() as usize)
                .unwrap_or(0),
            also_points: file
                .plots
                .also
                .iter()
                .map(|p| *p.get_ref() as usize)
                .collect(),
            log_time: file.plots.log_time,
            divergence_from_reference: file.plots.divergence_from_reference,
            sweep_max: file.plots.sweep_max,
            all_trajectories: file.plots.all_trajectories,
            main_plot: file.plots.main.clone(),
            series,
            series_span,
            phase,
            kind,
            minimise: None,
            stability,
            bvp,
            repeats,
        };
        let mut exp = exp;
        if let Some(m) = &file.minimise {
            exp.minimise = Some(minimise(&ctx, &exp, m)?);
        }
        let n = exp.points().len();
        if exp.plot_point >= n {
            let span = file.plots.point.as_ref().map(|p| p.span()).unwrap_or(0..0);
            return Err(ctx.err(
                span,
                "plots.point",
                format!("the sweep has {n} points (0..{})", n - 1),
            ));
        }
        for (k, p) in file.plots.also.iter().enumerate() {
            let i = *p.get_ref() as usize;
            if i >= n || i == exp.plot_point || exp.also_points[..k].contains(&i) {
                return Err(ctx.err(
                    p.span(),
                    "plots.also",
                    format!(
                        "point {i}: must be a point of the sweep (0..{}), other than plots.point \
                         and named once",
                        n - 1
                    ),
                ));
            }
        }
        // Every point must resolve: parameters in range, names known,
        // formulations applicable. Errors name the swept values.
        for p in exp.points() {
            exp.check_point(&p).map_err(|m| {
                SpecError(format!(
                    "{}: {}{m}",
                    path.display(),
                    describe(&exp.axes, &p.values)
                ))
            })?;
        }
        super::stability::check(&exp).map_err(|m| SpecError(format!("{}: {m}", path.display())))?;
        super::bvp::check(&exp).map_err(|m| SpecError(format!("{}: {m}", path.display())))?;
        Ok(exp)
    }

    /// The sweep points, in a fixed order.
    pub fn points(&self) -> Vec<crate::experiment::sweep::Point> {
        crate::experiment::sweep::points(self)
    }
}

/// The `[stability]` table of a stability experiment (refused elsewhere,
/// and a stability experiment refuses the tables it does not use).
fn stability(ctx: &Ctx, kind: Kind, file: &File) -> Result<Option<StabilitySpec>, SpecError> {
    let whole = |msg: &str| SpecError(format!("{}: {msg}", ctx.path.display()));
    let Some(st) = &file.stability else {
        if kind == Kind::Stability {
            return Err(whole(
                "an experiment of kind \"stability\" needs a [stability] table (over, range, \
                 samples)",
            ));
        }
        return Ok(None);
    };
    if kind != Kind::Stability {
        return Err(whole(
            "[stability] belongs to experiments of kind \"stability\" (set experiment.kind)",
        ));
    }
    for (present, table) in [
        (file.sweep.is_some(), "[sweep]"),
        (file.minimise.is_some(), "[minimise]"),
        (file.time.is_some(), "[time]"),
    ] {
        if present {
            return Err(whole(&format!(
                "{table} has no meaning in a stability experiment: [stability] gives the values \
                 swept, and a linearisation has no time span"
            )));
        }
    }
    for f in &file.formulations {
        if f.formulation.get_ref() == CLOSED_FORM {
            return Err(ctx.err(
                f.formulation.span(),
                "formulation.formulation",
                "a closed form has no linearisation",
            ));
        }
    }
    let over = st.over.get_ref().clone();
    let Some((table, name)) = over.split_once('.') else {
        return Err(ctx.err(
            st.over.span(),
            "stability.over",
            "must be `init.<name>` or `param.<name>`",
        ));
    };
    let params = entries(ctx, "params", &file.params)?;
    let info = nonholo_scenes::describe(file.experiment.scene.get_ref(), &params)
        .map_err(|e| ctx.err(file.experiment.scene.span(), "experiment.scene", e))?;
    if table == "param" && info.structural.contains(&name) {
        return Err(ctx.err(
            st.over.span(),
            "stability.over",
            format!(
                "`{name}` sets the size of scene `{}` (its coordinates): it cannot vary within \
                 one experiment",
                info.name
            ),
        ));
    }
    let known = match table {
        "param" => info
            .params
            .iter()
            .any(|p| p.name == name && matches!(p.kind, nonholo_core::Kind::Real { .. })),
        "init" => {
            info.coordinates
                .iter()
                .any(|c| c.name == name || name.strip_suffix("_dot").is_some_and(|b| b == c.name))
                || info.velocity_chart.iter().any(|c| c.name == name)
        }
        _ => false,
    };
    if !known {
        return Err(ctx.err(
            st.over.span(),
            "stability.over",
            format!(
                "`{over}`: must be `param.<p>` with a real parameter of `{}` or `init.<v>` with \
                 a coordinate, `<coord>_dot` or velocity-chart value of it",
                info.name
            ),
        ));
    }
    let [a, b] = *st.range.get_ref();
    if !(a.is_finite() && b.is_finite() && a < b && (b - a).is_finite()) {
        return Err(ctx.err(
            st.range.span(),
            "stability.range",
            "must be [from, to] with finite from < to and a finite width to − from",
        ));
    }
    let samples = *st.samples.get_ref() as usize;
    if !(2..=MAX_STABILITY_SAMPLES).contains(&samples) {
        return Err(ctx.err(
            st.samples.span(),
            "stability.samples",
            format!("must be between 2 and {MAX_STABILITY_SAMPLES}"),
        ));
    }
    for name in &st.independent {
        let coordinate = |n: &str| info.coordinates.iter().any(|c| c.name == n);
        let known = coordinate(name)
            || name.strip_suffix("_dot").is_some_and(coordinate)
            || name.strip_prefix("lambda").is_some_and(|k| {
                k.is_empty()
                    || k.parse::<usize>()
                        .is_ok_and(|k| (1..=info.s()).contains(&k))
            });
        if !known {
            return Err(whole(&format!(
                "`stability.independent`: `{name}` is not a state component of `{}` (a \
                 coordinate, `<coord>_dot`, or a multiplier `lambda…` of C)",
                info.name
            )));
        }
    }
    let steady_tol = match &st.steady_tol {
        None => nonholo_stability::Options::default().steady_tol,
        Some(t) => fields::positive_finite(*t.get_ref())
            .map_err(|m| ctx.err(t.span(), "stability.steady_tol", m))?,
    };
    let mut marks = Vec::new();
    for (name, v) in &st.marks {
        if !v.get_ref().is_finite() {
            return Err(ctx.err(
                v.span(),
                &format!("stability.marks.{name}"),
                "must be finite",
            ));
        }
        marks.push((name.clone(), *v.get_ref()));
    }
    let plot_range = |r: &Option<Spanned<[f64; 2]>>, key: &str| match r {
        None => Ok(None),
        Some(r) => {
            let [lo, hi] = *r.get_ref();
            if lo.is_finite() && hi.is_finite() && lo < hi {
                Ok(Some([lo, hi]))
            } else {
                Err(ctx.err(r.span(), key, "must be [low, high] with finite low < high"))
            }
        }
    };
    Ok(Some(StabilitySpec {
        over,
        range: [a, b],
        samples,
        independent: st.independent.clone(),
        marks,
        steady_tol,
        re_range: plot_range(&st.re_range, "stability.re_range")?,
        im_range: plot_range(&st.im_range, "stability.im_range")?,
    }))
}

/// `(t_end, output_every)` of a bvp experiment: its longest horizon, and
/// its finest grid (the initial-value lines are sampled there).
fn bvp_span(ctx: &Ctx, file: &File) -> Result<(f64, f64), SpecError> {
    let whole = |msg: &str| SpecError(format!("{}: {msg}", ctx.path.display()));
    let b = file
        .bvp
        .as_ref()
        .ok_or_else(|| whole("an experiment of kind \"bvp\" needs a [bvp] table"))?;
    let positive = |v: &Spanned<Vec<f64>>, key: &str| -> Result<Vec<f64>, SpecError> {
        let list = v.get_ref();
        if list.is_empty() || list.iter().any(|x| !(x.is_finite() && *x > 0.0)) {
            return Err(ctx.err(
                v.span(),
                key,
                "must be a non-empty list of positive numbers",
            ));
        }
        Ok(list.clone())
    };
    let horizons = positive(&b.horizons, "bvp.horizons")?;
    let h = positive(&b.h, "bvp.h")?;
    let t_end = horizons.iter().copied().fold(0.0, f64::max);
    let t_end = fields::t_end(t_end).map_err(|m| ctx.err(b.horizons.span(), "bvp.horizons", m))?;
    Ok((t_end, h.iter().copied().fold(f64::INFINITY, f64::min)))
}

/// Whether `x` is a whole multiple of `unit` (to 1e-9 relative).
fn whole_multiple(x: f64, unit: f64) -> Option<usize> {
    let k = (x / unit).round();
    ((x / unit - k).abs() <= 1e-9 * k.max(1.0) && k >= 1.0).then_some(k as usize)
}

/// The `[bvp]` table of a bvp experiment (refused elsewhere).
fn bvp(
    ctx: &Ctx,
    kind: Kind,
    file: &File,
    forms: &[FormulationSpec],
) -> Result<Option<BvpSpec>, SpecError> {
    let whole = |msg: &str| SpecError(format!("{}: {msg}", ctx.path.display()));
    let Some(b) = &file.bvp else {
        return Ok(None);
    };
    if kind != Kind::Bvp {
        return Err(whole(
            "[bvp] belongs to experiments of kind \"bvp\" (set experiment.kind)",
        ));
    }
    for (present, table) in [
        (file.minimise.is_some(), "[minimise]"),
        (file.stability.is_some(), "[stability]"),
        (file.work_precision.is_some(), "[work_precision]"),
    ] {
        if present {
            return Err(whole(&format!(
                "{table} has no meaning in a bvp experiment"
            )));
        }
    }
    let labels: Vec<&str> = forms.iter().map(|f| f.label.as_str()).collect();
    for f in forms {
        if f.formulation == CLOSED_FORM {
            return Err(whole(&format!(
                "{}: a closed form gives no initial-value run to take end data from; use an \
                 integrated formulation",
                f.label
            )));
        }
    }
    let ivp = |v: &Spanned<String>, key: &str| -> Result<String, SpecError> {
        if labels.contains(&v.get_ref().as_str()) {
            Ok(v.get_ref().clone())
        } else {
            Err(ctx.err(
                v.span(),
                key,
                format!(
                    "`{}` is not a [[formulation]] label ({})",
                    v.get_ref(),
                    labels.join(", ")
                ),
            ))
        }
    };
    let ends_from = ivp(&b.ends_from, "bvp.ends_from")?;
    let stationarity = b
        .stationarity
        .iter()
        .map(|v| ivp(v, "bvp.stationarity"))
        .collect::<Result<Vec<_>, _>>()?;
    let mut h = b.h.get_ref().clone();
    h.sort_by(|a, b| b.total_cmp(a));
    h.dedup();
    let mut horizons = b.horizons.get_ref().clone();
    horizons.sort_by(f64::total_cmp);
    horizons.dedup();
    for pair in h.windows(2) {
        if whole_multiple(pair[0], pair[1]).is_none_or(|k| k < 2) {
            return Err(ctx.err(
                b.h.span(),
                "bvp.h",
                format!(
                    "{} is not a whole multiple (2 or more) of the next finer spacing {}: each \
                     grid's nodes must be nodes of the next finer one",
                    fields::num(pair[0]),
                    fields::num(pair[1])
                ),
            ));
        }
    }
    for &t1 in &horizons {
        for &x in &h {
            let nodes = whole_multiple(t1, x).ok_or_else(|| {
                ctx.err(
                    b.horizons.span(),
                    "bvp.horizons",
                    format!(
                        "{} is not a whole number of steps h = {}",
                        fields::num(t1),
                        fields::num(x)
                    ),
                )
            })?;
            if !(2..MAX_BVP_NODES).contains(&nodes) {
                return Err(ctx.err(
                    b.h.span(),
                    "bvp.h",
                    format!(
                        "{nodes} intervals on a horizon of {}: between 2 and {MAX_BVP_NODES}",
                        fields::num(t1)
                    ),
                ));
            }
        }
    }
    let start_from_reference = match &b.start {
        None => true,
        Some(v) => match v.get_ref().as_str() {
            "reference" => true,
            "line" => false,
            other => {
                return Err(ctx.err(
                    v.span(),
                    "bvp.start",
                    format!("`{other}`: valid: reference (ends_from's motion), line"),
                ));
            }
        },
    };
    let tol = match &b.tol {
        None => nonholo_variational::Options::default().tol,
        Some(t) => fields::rtol(*t.get_ref()).map_err(|m| ctx.err(t.span(), "bvp.tol", m))?,
    };
    let max_iter = match &b.max_iter {
        None => nonholo_variational::Options::default().max_iter,
        Some(m) if (1..=10_000).contains(m.get_ref()) => *m.get_ref() as usize,
        Some(m) => return Err(ctx.err(m.span(), "bvp.max_iter", "must be 1 to 10000")),
    };
    if b.lines.is_empty() {
        return Err(whole("[bvp] needs at least one [[bvp.line]]"));
    }
    let params = entries(ctx, "params", &file.params)?;
    let info = nonholo_scenes::describe(file.experiment.scene.get_ref(), &params)
        .map_err(|e| ctx.err(file.experiment.scene.span(), "experiment.scene", e))?;
    let mut lines: Vec<BvpLine> = Vec::new();
    for l in &b.lines {
        let label = l.label.get_ref().clone();
        check_label(&label).map_err(|m| ctx.err(l.label.span(), "bvp.line.label", m))?;
        if labels.contains(&label.as_str()) || lines.iter().any(|x| x.label == label) {
            return Err(ctx.err(
                l.label.span(),
                "bvp.line.label",
                format!("`{label}` is used twice (labels name lines of every table)"),
            ));
        }
        let resolved = crate::bvp::formulation(
            info,
            l.formulation.get_ref(),
            &l.dependent,
            l.ends.as_ref().map(|e| e.get_ref().as_str()),
            l.map_form.as_ref().map(|e| e.get_ref().as_str()),
        )
        .map_err(|(field, m)| {
            let span = match field {
                "ends" => l.ends.as_ref().map(|e| e.span()),
                "map_form" => l.map_form.as_ref().map(|e| e.span()),
                _ => None,
            };
            ctx.err(
                span.unwrap_or_else(|| l.formulation.span()),
                &format!("bvp.line.{field}"),
                m,
            )
        })?;
        lines.push(BvpLine {
            label,
            formulation: l.formulation.get_ref().clone(),
            dependent: l.dependent.clone(),
            ends: l.ends.as_ref().map(|e| e.get_ref().clone()),
            map_form: l.map_form.as_ref().map(|e| e.get_ref().clone()),
            resolved,
        });
    }
    let mut stationarity_under = Vec::new();
    for v in &b.stationarity_under {
        if !lines.iter().any(|l| l.label == *v.get_ref()) {
            return Err(ctx.err(
                v.span(),
                "bvp.stationarity_under",
                format!("`{}` is not a [[bvp.line]] label", v.get_ref()),
            ));
        }
        stationarity_under.push(v.get_ref().clone());
    }
    if stationarity_under.is_empty() {
        stationarity_under = lines.iter().map(|l| l.label.clone()).collect();
    }
    Ok(Some(BvpSpec {
        ends_from,
        h,
        horizons,
        stationarity,
        stationarity_under,
        start_from_reference,
        tol,
        max_iter,
        lines,
    }))
}

/// Fills the ladder and reference of every line of a work-precision
/// experiment (and refuses work-precision keys elsewhere); returns the
/// number of timed repeats.
fn work_precision_lines(
    ctx: &Ctx,
    kind: Kind,
    file: &File,
    forms: &mut [FormulationSpec],
    t_end: f64,
) -> Result<usize, SpecError> {
    if kind != Kind::WorkPrecision {
        if file.work_precision.is_some() {
            return Err(SpecError(format!(
                "{}: `work_precision` belongs to experiments of kind \"work-precision\" \
                 (set experiment.kind)",
                ctx.path.display()
            )));
        }
        for f in &file.formulations {
            if f.tolerances.is_some() || f.steps.is_some() || f.reference.is_some() {
                return Err(ctx.err(
                    f.label.span(),
                    "formulation.tolerances",
                    "tolerances, steps and reference belong to work-precision experiments",
                ));
            }
        }
        return match &file.measures.repeats {
            None => Ok(1),
            Some(r) if (1..=1000).contains(r.get_ref()) => Ok(*r.get_ref() as usize),
            Some(r) => Err(ctx.err(r.span(), "measures.repeats", "must be between 1 and 1000")),
        };
    }
    if let Some(r) = &file.measures.repeats {
        return Err(ctx.err(
            r.span(),
            "measures.repeats",
            "work-precision experiments set their repeats in [work_precision]",
        ));
    }
    let Some(wp) = &file.work_precision else {
        return Err(SpecError(format!(
            "{}: a work-precision experiment needs a [work_precision] table (tolerances, steps, \
             repeats, reference)",
            ctx.path.display()
        )));
    };
    let repeats = match &wp.repeats {
        None => 5,
        Some(r) if (1..=1000).contains(r.get_ref()) => *r.get_ref() as usize,
        Some(r) => {
            return Err(ctx.err(
                r.span(),
                "work_precision.repeats",
                "must be between 1 and 1000",
            ));
        }
    };
    let global_tol = tolerances(ctx, &wp.tolerances, "work_precision.tolerances")?;
    let global_steps = steps(ctx, &wp.steps, "work_precision.steps")?;
    for (f, spec) in file.formulations.iter().zip(forms.iter_mut()) {
        if spec.formulation == CLOSED_FORM {
            return Err(ctx.err(
                f.formulation.span(),
                "formulation.formulation",
                "a closed form is the reference of a work-precision line, not a line",
            ));
        }
        if let Some(s) = &f.step {
            return Err(ctx.err(
                s.span(),
                "formulation.step",
                "work-precision lines take `steps = [...]` (step counts over the span)",
            ));
        }
        let method = fields::method(&spec.settings.integrator)
            .map_err(|m| ctx.err(f.label.span(), "formulation.integrator", m))?;
        let ladder = if method.needs_fixed_step() {
            let st = steps(ctx, &f.steps, "formulation.steps")?
                .or(global_steps.clone())
                .ok_or_else(|| {
                    ctx.err(
                        f.label.span(),
                        "formulation.steps",
                        format!(
                            "`{}` has a fixed step: give `steps = [...]` here or in [work_precision]",
                            spec.settings.integrator
                        ),
                    )
                })?;
            spec.settings.step = Some(t_end / st[0] as f64);
            Ladder::Steps(st)
        } else {
            let tol = tolerances(ctx, &f.tolerances, "formulation.tolerances")?
                .or(global_tol.clone())
                .ok_or_else(|| {
                    ctx.err(
                        f.label.span(),
                        "formulation.tolerances",
                        "give `tolerances = [...]` here or in [work_precision]",
                    )
                })?;
            Ladder::Tolerances(tol)
        };
        let base = reference(
            ctx,
            RefSpec::default_for(&spec.formulation),
            wp.reference.as_ref(),
            "work_precision.reference",
        )?;
        let refspec = reference(ctx, base, f.reference.as_ref(), "formulation.reference")?;
        spec.work_precision = Some((ladder, refspec));
    }
    Ok(repeats)
}

fn tolerances(
    ctx: &Ctx,
    v: &Option<Spanned<Vec<f64>>>,
    key: &str,
) -> Result<Option<Vec<f64>>, SpecError> {
    let Some(v) = v else { return Ok(None) };
    let list = v.get_ref();
    ladder_length(ctx, v, key)?;
    // Each value is run as rtol = atol: both ranges apply.
    for t in list {
        fields::rtol(*t)
            .and_then(fields::atol)
            .map_err(|m| ctx.err(v.span(), key, m))?;
    }
    Ok(Some(list.clone()))
}

/// A ladder (of tolerances or step counts) holds 1 to
/// [`fields::MAX_LADDER`] values.
fn ladder_length<T>(ctx: &Ctx, v: &Spanned<Vec<T>>, key: &str) -> Result<(), SpecError> {
    let n = v.get_ref().len();
    if n == 0 {
        return Err(ctx.err(v.span(), key, "empty list"));
    }
    if n > fields::MAX_LADDER {
        return Err(ctx.err(
            v.span(),
            key,
            format!("{n} values: a ladder has at most {}", fields::MAX_LADDER),
        ));
    }
    Ok(())
}

fn steps(
    ctx: &Ctx,
    v: &Option<Spanned<Vec<i64>>>,
    key: &str,
) -> Result<Option<Vec<usize>>, SpecError> {
    let Some(v) = v else { return Ok(None) };
    let list = v.get_ref();
    ladder_length(ctx, v, key)?;
    if let Some(bad) = list.iter().find(|n| !(1..=10_000_000).contains(*n)) {
        return Err(ctx.err(
            v.span(),
            key,
            format!("{bad}: step counts must lie in [1, 1e7]"),
        ));
    }
    Ok(Some(list.iter().map(|n| *n as usize).collect()))
}

/// `base` overridden by the keys given in `file`.
fn reference(
    ctx: &Ctx,
    base: RefSpec,
    file: Option<&ReferenceFile>,
    key: &str,
) -> Result<RefSpec, SpecError> {
    let Some(f) = file else { return Ok(base) };
    let mut r = base;
    for (given, field, sub) in [
        (&f.integrator, &mut r.integrator, "integrator"),
        (
            &f.check_integrator,
            &mut r.check_integrator,
            "check_integrator",
        ),
    ] {
        if let Some(name) = given {
            let method = fields::method(name.get_ref())
                .map_err(|m| ctx.err(name.span(), &format!("{key}.{sub}"), m))?;
            if method.needs_fixed_step() {
                return Err(ctx.err(
                    name.span(),
                    &format!("{key}.{sub}"),
                    "a reference needs an adaptive method with an error estimate",
                ));
            }
            *field = name.get_ref().clone();
        }
    }
    for (given, field, sub) in [
        (&f.rtol, &mut r.rtol, "rtol"),
        (&f.check_rtol, &mut r.check_rtol, "check_rtol"),
    ] {
        if let Some(v) = given {
            *field = fields::rtol(*v.get_ref())
                .map_err(|m| ctx.err(v.span(), &format!("{key}.{sub}"), m))?;
        }
    }
    if let Some(v) = &f.max_wall_time {
        r.max_wall_time = Some(
            fields::max_wall_time(*v.get_ref())
                .map_err(|m| ctx.err(v.span(), &format!("{key}.max_wall_time"), m))?,
        );
    }
    if let Some(v) = &f.max_steps {
        r.max_steps = fields::max_steps(*v.get_ref())
            .map_err(|m| ctx.err(v.span(), &format!("{key}.max_steps"), m))?;
    }
    if let Some(c) = f.closed_form {
        r.closed_form = c;
    }
    if !f.options.is_empty() {
        r.options = override_with(
            &r.options,
            &entries(ctx, &format!("{key}.options"), &f.options)?,
        );
    }
    Ok(r)
}

/// Checks `[minimise]` against the experiment it belongs to.
fn minimise(ctx: &Ctx, exp: &Experiment, m: &MinimiseFile) -> Result<MinimiseSpec, SpecError> {
    if exp.kind != Kind::Compare {
        return Err(ctx.err(
            m.over.span(),
            "minimise",
            "belongs to experiments of kind \"compare\"",
        ));
    }
    let labels: Vec<String> = exp.formulations.iter().map(|f| f.label.clone()).collect();
    let over = m.over.get_ref().clone();
    let target = parse_target(&over, &labels)
        .and_then(|t| fixed_size(&exp.scene, t))
        .map_err(|e| ctx.err(m.over.span(), "minimise.over", e))?;
    if target == Target::Case || exp.axes.iter().any(|a| a.name == over) {
        return Err(ctx.err(
            m.over.span(),
            "minimise.over",
            "must be a numeric name the sweep does not already vary",
        ));
    }
    let [lo, hi] = *m.range.get_ref();
    if !(lo.is_finite() && hi.is_finite() && lo < hi && (hi - lo).is_finite()) {
        return Err(ctx.err(
            m.range.span(),
            "minimise.range",
            "must be [low, high], finite, low < high, with a finite width high − low",
        ));
    }
    let samples = match &m.samples {
        None => 201,
        Some(n) if (3..=100_000).contains(n.get_ref()) => *n.get_ref() as usize,
        Some(n) => {
            return Err(ctx.err(n.span(), "minimise.samples", "must be between 3 and 100000"));
        }
    };
    let refine = match &m.refine {
        None => 3,
        Some(n) if *n.get_ref() as usize <= samples => *n.get_ref() as usize,
        Some(n) => {
            return Err(ctx.err(
                n.span(),
                "minimise.refine",
                "must be at most minimise.samples",
            ));
        }
    };
    let label = m.label.get_ref().clone();
    if !labels.contains(&label) || label == exp.reference {
        return Err(ctx.err(
            m.label.span(),
            "minimise.label",
            format!(
                "must be a formulation other than the reference {} (one of {})",
                exp.reference,
                labels.join(", ")
            ),
        ));
    }
    // Only the minimised formulation may change with the value: a name that
    // moved the reference too would compare two motions that both change.
    let owner = match &target {
        Target::FormParam(l, _)
        | Target::FormInit(l, _)
        | Target::FormOption(l, _)
        | Target::FormSetting(l, _) => Some(l.as_str()),
        _ => None,
    };
    if owner != Some(m.label.get_ref().as_str()) {
        return Err(ctx.err(
            m.over.span(),
            "minimise.over",
            format!(
                "must be a name of the minimised formulation alone (`{0}.init.…`, `{0}.param.…`, \
                 `{0}.option.…`), so that the reference does not change with it",
                m.label.get_ref()
            ),
        ));
    }
    let spec = MinimiseSpec {
        over,
        target,
        range: [lo, hi],
        samples,
        refine,
        label,
    };
    // Both ends of the range must resolve at the first point, like every
    // swept value (names known, values in range).
    if let Some(first) = exp.points().into_iter().next() {
        for v in [lo, hi] {
            let (e, p) = spec.at(exp, &first, v);
            e.check_point(&p).map_err(|msg| {
                ctx.err(
                    m.range.span(),
                    "minimise.range",
                    format!("{} = {v}: {msg}", spec.over),
                )
            })?;
        }
    }
    Ok(spec)
}

/// `at alpha = 0.3, a = 0.4: ` for messages about one point.
pub fn describe(axes: &[Axis], values: &[String]) -> String {
    if axes.is_empty() {
        return String::new();
    }
    let parts: Vec<String> = axes
        .iter()
        .zip(values)
        .map(|(a, v)| {
            if a.line > 0 {
                format!("{} = {v} (swept at line {})", a.name, a.line)
            } else {
                format!("{} = {v}", a.name)
            }
        })
        .collect();
    format!("at {}: ", parts.join(", "))
}

/// A point's coordinates for titles and legends: `alpha = 0.3, a = 0.4`
/// (axis names without their `param.`/`init.`/`option.` prefix, numbers to
/// four significant digits in their shortest form; empty without a sweep).
pub fn compact(axes: &[Axis], values: &[String]) -> String {
    axes.iter()
        .zip(values)
        .map(|(a, v)| {
            let name = a.name.rsplit('.').next().unwrap_or(&a.name);
            // Four significant digits, large and small values in scientific
            // notation: a title reads `phi = 3.142`, `N = 1e6`.
            let v = v
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .map(|x| {
                    if x == 0.0 {
                        "0".to_string()
                    } else {
                        crate::table::readable(&format!("{x:e}"))
                    }
                })
                .unwrap_or(v.clone());
            format!("{name} = {v}")
        })
        .fold(Vec::<String>::new(), |mut seen, item| {
            // A value swept for several formulations at once reads once.
            if !seen.contains(&item) {
                seen.push(item);
            }
            seen
        })
        .join(", ")
}
