//! The resume key of a sweep point: which stored point file holds the
//! computation a point asks for.
//!
//! The key is the first 16 hex digits of the SHA-256 of a canonical
//! serialisation of the resolved point ([`canonical`]): compact JSON of
//! structs with a fixed field order, holding everything the point's results
//! depend on —
//! - the point file's schema and the version of nonholo;
//! - for every formulation, in the experiment's order: its label, scene,
//!   formulation, resolved scene parameters, initial data and options (the
//!   text they are given as, in their order), every integration setting
//!   (radau5's only where Radau IIA runs for the line, as its integrator
//!   or its reference's: elsewhere they change nothing and are keyed as
//!   their values of before they existed), the time span and output
//!   spacing, and for a work-precision line its ladder and reference;
//! - the kind's measures: the divergence threshold of a comparison (and
//!   the quantity whose sign changes it counts, if any), the timed repeats
//!   of a work-precision experiment.
//!
//! Floats are written as their IEEE-754 bits in hex, so values one ulp
//! apart (or `0` and `−0`) give different keys and nothing depends on how a
//! float prints; there are no maps, so no key order to settle. What does
//! not change the computation (title, claim, plots, other points) is not in
//! the key. Every [`Settings`], [`RefSpec`] field is destructured by name:
//! a new setting does not compile until the key holds it.

use nonholo_core::integrate::{Method, RadauDense};
use serde::{Serialize, Serializer};
use sha2::{Digest, Sha256};

use super::spec::{Experiment, FormulationSpec, Kind, Ladder, RefSpec, Settings};
use super::sweep::{Point, apply_point, resolve};

/// A float by its exact bits.
struct Bits(f64);

impl Serialize for Bits {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(&format_args!("{:016x}", self.0.to_bits()))
    }
}

#[derive(Serialize)]
struct PointKey<'a> {
    schema: &'a str,
    version: &'a str,
    runs: Vec<RunKey<'a>>,
    measures: Measures,
}

#[derive(Serialize)]
enum Measures {
    Compare {
        threshold: Bits,
        /// Left out when not asked for, so that keys made before it existed
        /// stay valid.
        #[serde(skip_serializing_if = "Option::is_none")]
        reversals: Option<String>,
        /// Timed repeats; left out at 1 (the keys of single runs unchanged).
        #[serde(skip_serializing_if = "is_one")]
        repeats: usize,
    },
    /// A stability sweep stores no points; its key is never asked for.
    Stability,
    /// Nor does a bvp experiment.
    Bvp,
    WorkPrecision {
        repeats: usize,
    },
}

#[derive(Serialize)]
struct RunKey<'a> {
    label: &'a str,
    scene: &'a str,
    formulation: &'a str,
    params: &'a [(String, String)],
    init: &'a [(String, String)],
    options: &'a [(String, String)],
    t_end: Bits,
    output_every: Bits,
    settings: SettingsKey<'a>,
    work_precision: Option<(LadderKey, RefKey<'a>)>,
}

#[derive(Serialize)]
struct SettingsKey<'a> {
    integrator: &'a str,
    rtol: Bits,
    atol: Bits,
    step: Option<Bits>,
    max_steps: usize,
    max_wall_time: Option<Bits>,
    project_init: bool,
    radau_newton: &'a str,
    /// Left out when `collocation`, so that keys made before the setting
    /// existed still name the same runs.
    #[serde(skip_serializing_if = "is_collocation")]
    radau_dense: &'a str,
    /// Left out at `0.001` (the default, RADAU5's), the value runs were
    /// made with before the setting existed, so that their keys still name
    /// them.
    #[serde(skip_serializing_if = "is_radau5_reuse")]
    radau_jacobian_reuse: Bits,
    /// Left out when not given (RADAU5's tolerance-dependent default), as
    /// every run was made before the setting existed.
    #[serde(skip_serializing_if = "Option::is_none")]
    radau_newton_tol: Option<Bits>,
    /// Left out when off, so that keys made before the setting existed
    /// still name the same runs.
    #[serde(skip_serializing_if = "is_false")]
    stiff_stop: bool,
}

fn is_collocation(s: &&str) -> bool {
    *s == RadauDense::Collocation.name()
}

/// radau5's Jacobian reuse of every run made before it was a setting
/// (RADAU5's `THET`): a key leaves it out, whatever the default becomes.
const REUSE_BEFORE_SETTING: f64 = 0.001;

fn is_radau5_reuse(b: &Bits) -> bool {
    b.0 == REUSE_BEFORE_SETTING
}

fn is_false(b: &bool) -> bool {
    !*b
}

fn is_one(n: &usize) -> bool {
    *n == 1
}

impl<'a> SettingsKey<'a> {
    /// The key of `s`; `radau` says whether Radau IIA runs for the line
    /// (as its integrator or its reference's). Without it the Radau
    /// settings change nothing and are keyed as their values of before
    /// they existed (and so left out), which keeps the keys of the other
    /// integrators' runs.
    fn new(s: &'a Settings, radau: bool) -> Self {
        let Settings {
            integrator,
            rtol,
            atol,
            step,
            max_steps,
            max_wall_time,
            project_init,
            radau_newton,
            radau_dense,
            radau_jacobian_reuse,
            radau_newton_tol,
            stiff_stop,
        } = s;
        SettingsKey {
            integrator,
            rtol: Bits(*rtol),
            atol: Bits(*atol),
            step: step.map(Bits),
            max_steps: *max_steps,
            max_wall_time: max_wall_time.map(Bits),
            project_init: *project_init,
            radau_newton,
            radau_dense: if radau {
                radau_dense
            } else {
                RadauDense::Collocation.name()
            },
            radau_jacobian_reuse: Bits(if radau {
                *radau_jacobian_reuse
            } else {
                REUSE_BEFORE_SETTING
            }),
            radau_newton_tol: radau_newton_tol.filter(|_| radau).map(Bits),
            stiff_stop: *stiff_stop,
        }
    }
}

#[derive(Serialize)]
enum LadderKey {
    Tolerances(Vec<Bits>),
    Steps(Vec<usize>),
}

impl From<&Ladder> for LadderKey {
    fn from(l: &Ladder) -> Self {
        match l {
            Ladder::Tolerances(t) => LadderKey::Tolerances(t.iter().map(|v| Bits(*v)).collect()),
            Ladder::Steps(n) => LadderKey::Steps(n.clone()),
        }
    }
}

#[derive(Serialize)]
struct RefKey<'a> {
    closed_form: bool,
    integrator: &'a str,
    rtol: Bits,
    check_integrator: &'a str,
    check_rtol: Bits,
    max_wall_time: Option<Bits>,
    /// Left out at its default, so that keys from before it existed hold.
    #[serde(skip_serializing_if = "is_default_steps")]
    max_steps: usize,
    /// Left out when the reference runs the line's own options.
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    options: &'a [(String, String)],
}

fn is_default_steps(n: &usize) -> bool {
    *n == crate::simulate::DEFAULT_MAX_STEPS
}

impl<'a> From<&'a RefSpec> for RefKey<'a> {
    fn from(r: &'a RefSpec) -> Self {
        let RefSpec {
            closed_form,
            integrator,
            rtol,
            check_integrator,
            check_rtol,
            max_wall_time,
            max_steps,
            options,
        } = r;
        RefKey {
            closed_form: *closed_form,
            integrator,
            rtol: Bits(*rtol),
            check_integrator,
            check_rtol: Bits(*check_rtol),
            max_wall_time: max_wall_time.map(Bits),
            max_steps: *max_steps,
            options,
        }
    }
}

/// Whether Radau IIA runs for `f`: as its integrator, or as its
/// work-precision reference or the reference's check.
fn uses_radau(f: &FormulationSpec) -> bool {
    let radau = Method::Radau5.name();
    f.settings.integrator == radau
        || f.work_precision
            .as_ref()
            .is_some_and(|(_, r)| r.integrator == radau || r.check_integrator == radau)
}

/// The canonical serialisation of `point` of `exp` for point files of
/// `schema` (see the module documentation).
pub fn canonical(exp: &Experiment, point: &Point, schema: &str) -> Result<String, String> {
    let runs = resolve(exp, point)?;
    let forms: Vec<FormulationSpec> = apply_point(exp, point)?.forms;
    let runs = runs
        .iter()
        .zip(&forms)
        .map(|(r, f)| RunKey {
            label: &r.label,
            scene: &r.spec.scene,
            formulation: &r.spec.formulation,
            params: &r.spec.params,
            init: &r.spec.init,
            options: &r.spec.options,
            t_end: Bits(exp.t_end),
            output_every: Bits(exp.output_every),
            settings: SettingsKey::new(&f.settings, uses_radau(f)),
            work_precision: f
                .work_precision
                .as_ref()
                .map(|(l, r)| (LadderKey::from(l), RefKey::from(r))),
        })
        .collect();
    let measures = match exp.kind {
        Kind::Compare => Measures::Compare {
            threshold: Bits(exp.threshold),
            reversals: exp.reversals.clone(),
            repeats: exp.repeats,
        },
        Kind::WorkPrecision => Measures::WorkPrecision {
            repeats: exp.repeats,
        },
        Kind::Stability => Measures::Stability,
        Kind::Bvp => Measures::Bvp,
    };
    serde_json::to_string(&PointKey {
        schema,
        version: env!("CARGO_PKG_VERSION"),
        runs,
        measures,
    })
    .map_err(|e| e.to_string())
}

/// The resume key of `point` of `exp` for point files of `schema`: the
/// first 16 hex digits of the SHA-256 of [`canonical`].
pub fn point_key(exp: &Experiment, point: &Point, schema: &str) -> Result<String, String> {
    let digest = Sha256::digest(canonical(exp, point, schema)?.as_bytes());
    Ok(digest.iter().take(8).map(|b| format!("{b:02x}")).collect())
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn experiment(rtol: &str, threshold: &str, title: &str) -> Experiment {
        parse(&experiment_text(rtol, threshold, title))
    }

    fn parse(text: &str) -> Experiment {
        Experiment::parse(Path::new("experiments/key.toml"), text).unwrap()
    }

    /// The file of [`experiment`]: B (DOP853 by default) and C on the
    /// rolling disk, two points.
    fn experiment_text(rtol: &str, threshold: &str, title: &str) -> String {
        format!(
            r#"[experiment]
name = "key"
title = "{title}"
claim = "none"
scene = "rolling-disk"

[init]
omega_theta = 0.5
omega_psi = 1.0

[time]
t_end = 1.0
output_every = 0.1

[[formulation]]
label = "B"
formulation = "chetaev"
rtol = {rtol}
atol = 1e-12

[[formulation]]
label = "C"
formulation = "vakonomic"

[sweep]
mode = "grid"
values = {{ "C.init.lambda1" = [0.5, 1.0] }}

[measures]
threshold = {threshold}
"#
        )
    }

    fn keys(exp: &Experiment) -> Vec<String> {
        exp.points()
            .iter()
            .map(|p| point_key(exp, p, "nonholo.point/1").unwrap())
            .collect()
    }

    /// The key of a fixed point, pinned: it must not change between runs,
    /// machines or builds (a change here invalidates every stored point and
    /// must be deliberate).
    #[test]
    fn the_key_is_stable() {
        let exp = experiment("1e-10", "1e-6", "t");
        let k = keys(&exp);
        assert_eq!(k, keys(&experiment("1e-10", "1e-6", "t")));
        assert_eq!(k, ["cee2eded190f3606", "9b6e16a4525cdf30"]);
    }

    /// Points that differ in one swept value, settings one ulp apart, or a
    /// threshold one ulp apart have different keys; the title changes
    /// nothing.
    #[test]
    fn the_key_tells_points_apart() {
        let base = keys(&experiment("1e-10", "1e-6", "t"));
        assert_ne!(base[0], base[1]);
        let up = 1e-10f64.next_up();
        assert_ne!(format!("{up:e}"), "1e-10");
        let ulp = keys(&experiment(&format!("{up:e}"), "1e-6", "t"));
        assert_ne!(ulp[0], base[0]);
        assert_ne!(ulp[1], base[1]);
        let threshold = keys(&experiment(
            "1e-10",
            &format!("{:e}", 1e-6f64.next_down()),
            "t",
        ));
        assert_ne!(threshold[0], base[0]);
        assert_eq!(keys(&experiment("1e-10", "1e-6", "another title")), base);
        let exp = experiment("1e-10", "1e-6", "t");
        let p = &exp.points()[0];
        assert_ne!(
            point_key(&exp, p, "nonholo.point/1").unwrap(),
            point_key(&exp, p, "nonholo.wp-point/1").unwrap()
        );
    }

    /// radau5's settings are in the key of a line that Radau IIA runs and
    /// nowhere else: on B by DOP853 they change nothing; on B by radau5
    /// the continuous extension and the Jacobian reuse each change the key,
    /// and `collocation` with RADAU5's `0.001`, the settings of every run
    /// before either existed, leave both out.
    #[test]
    fn radau_settings_are_keyed_where_radau_runs() {
        // B's settings, given `extra`; the key of the first point and its
        // canonical text.
        let key = |extra: &str| {
            let text = experiment_text("1e-10", "1e-6", "t").replace(
                "rtol = 1e-10\natol = 1e-12",
                &format!("rtol = 1e-10\n{extra}"),
            );
            let exp = parse(&text);
            (
                point_key(&exp, &exp.points()[0], "nonholo.point/1").unwrap(),
                canonical(&exp, &exp.points()[0], "s").unwrap(),
            )
        };
        let dop = key("integrator = \"dop853\"");
        let dop_radau =
            key("integrator = \"dop853\"\nradau_dense = \"hermite\"\nradau_jacobian_reuse = 0.1");
        assert_eq!(dop.0, dop_radau.0);
        assert!(!dop.1.contains("radau_dense") && !dop.1.contains("radau_jacobian_reuse"));
        // A DOP853 line whose work-precision reference is Radau IIA: the
        // reference runs the line's radau5 settings, so they are keyed.
        let wp = |dense: &str| {
            let text = format!(
                r#"[experiment]
name = "key"
kind = "work-precision"
title = "t"
claim = "none"
scene = "rolling-disk"

[time]
t_end = 1.0
output_every = 0.1

[work_precision]
tolerances = [1e-6]
reference = {{ integrator = "radau5" }}

[[formulation]]
label = "B"
formulation = "chetaev"
integrator = "dop853"
radau_dense = "{dense}"
"#
            );
            let exp = parse(&text);
            point_key(&exp, &exp.points()[0], "nonholo.wp-point/1").unwrap()
        };
        assert_ne!(wp("collocation"), wp("hermite"));
        let radau = |extra: &str| key(&format!("integrator = \"radau5\"\n{extra}"));
        let auto = radau("");
        assert!(auto.1.contains(r#""radau_dense":"auto""#), "{}", auto.1);
        let old = radau("radau_dense = \"collocation\"");
        assert!(!old.1.contains("radau_dense") && !old.1.contains("radau_jacobian_reuse"));
        let lax = radau("radau_jacobian_reuse = 0.1");
        let hermite = radau("radau_dense = \"hermite\"");
        let tight = radau("radau_newton_tol = 1e-6");
        assert!(!auto.1.contains("radau_newton_tol"));
        let dop_tight = key("integrator = \"dop853\"\nradau_newton_tol = 1e-6");
        assert_eq!(dop.0, dop_tight.0);
        let all = [&auto.0, &old.0, &lax.0, &hermite.0, &tight.0];
        for (i, a) in all.iter().enumerate() {
            for b in &all[i + 1..] {
                assert_ne!(a, b);
            }
        }
    }

    #[test]
    fn floats_are_written_by_their_bits() {
        let exp = experiment("1e-10", "1e-6", "t");
        let text = canonical(&exp, &exp.points()[0], "s").unwrap();
        assert!(
            text.contains(&format!("\"rtol\":\"{:016x}\"", 1e-10f64.to_bits())),
            "{text}"
        );
        assert!(text.contains(r#"["lambda1","0.5"]"#), "{text}");
    }
}
