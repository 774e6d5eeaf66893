//! `nonholo bvp` and experiments of kind `bvp` from the command line: the
//! files they write (the run schema with its `bvp` object), the
//! stationarity residual, and what they refuse (status 2 naming the field;
//! status 1 for a solve that fails, nothing written).

mod common;

use common::*;

fn out(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// C's motion of the sleigh on [0, 1] s (every 5 ms), and B's, as run files.
fn runs(dir: &std::path::Path) {
    for (f, extra) in [("vakonomic", "--init=lambda=0.5"), ("chetaev", "")] {
        let mut args = vec![
            "simulate",
            "--scene",
            "sleigh-incline",
            "--formulation",
            f,
            "--init",
            "phi=0.3",
            "--init",
            "u=2",
            "--init",
            "omega=0.7",
            "--t-end",
            "1",
            "--output-every",
            "0.005",
            "--rtol",
            "1e-13",
            "--atol",
            "1e-13",
            "--out",
        ];
        let name = format!("{f}.json");
        args.push(&name);
        if !extra.is_empty() {
            args.push(extra);
        }
        let o = nonholo_in(dir, &args);
        assert!(o.status.success(), "{}", stderr(&o));
    }
}

/// With the ends of C's run, C's boundary-value problem on 201 nodes is C's
/// motion to its discretisation error (the refinement's own estimate), in
/// the run schema: the nodes, velocities by differences, C's multiplier
/// and the `bvp` object; the CSV form carries the same numbers.
#[test]
fn bvp_writes_a_run_file_with_its_bvp_object() {
    let dir = scratch("bvp-cli");
    runs(&dir);
    let o = nonholo_in(
        &dir,
        &[
            "bvp",
            "--ends-from",
            "vakonomic.json",
            "--nodes",
            "51",
            "--refine",
            "--out",
            "c-bvp.json",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("c-bvp.json")).unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["schema"], "nonholo.run/1");
    assert_eq!(v["formulation"], "vakonomic");
    assert_eq!(v["integrator"]["method"], "bvp-midpoint");
    assert_eq!(v["status"], "completed");
    let b = &v["bvp"];
    assert_eq!(b["variant"], "vakonomic");
    assert_eq!(b["nodes"], 201);
    assert_eq!(b["levels"].as_array().unwrap().len(), 3);
    let r = &b["refinement"];
    assert!((r["order"].as_f64().unwrap() - 2.0).abs() < 0.1, "{r}");
    // The written path against C's run (every 5 ms = every node).
    let c: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("vakonomic.json")).unwrap())
            .unwrap();
    let diff = v["q"]
        .as_array()
        .unwrap()
        .iter()
        .zip(c["q"].as_array().unwrap())
        .flat_map(|(a, b)| {
            a.as_array()
                .unwrap()
                .iter()
                .zip(b.as_array().unwrap())
                .map(|(x, y)| (x.as_f64().unwrap() - y.as_f64().unwrap()).abs())
                .collect::<Vec<_>>()
        })
        .fold(0.0f64, f64::max);
    let estimate = r["error_estimate"].as_f64().unwrap();
    assert!(
        diff < 2.0 * estimate && diff > 0.5 * estimate,
        "{diff:e} against the estimate {estimate:e}"
    );
    // C's multiplier at the nodes, against the run's state λ.
    let l0 = v["lambda"][0][0].as_f64().unwrap();
    assert!((l0 - 0.5).abs() < 1e-3, "{l0}");
    // The CSV form.
    let o = nonholo_in(
        &dir,
        &[
            "bvp",
            "--ends-from",
            "vakonomic.json",
            "--nodes",
            "201",
            "--out",
            "c-bvp.csv",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let rows = csv_rows(&dir.join("c-bvp.csv"));
    assert_eq!(rows.len(), 201);
    assert!(rows[0].contains_key("lambda") && rows[0].contains_key("phi_dot"));
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("c-bvp.csv.meta.json")).unwrap())
            .unwrap();
    assert_eq!(meta["bvp"]["nodes"], 201);
    assert!(meta.get("q").is_none());
}

/// `--stationarity-of`: C's motion is stationary up to the discretisation,
/// B's is not (a residual of order one, in N m).
#[test]
fn bvp_measures_the_stationarity_of_a_motion() {
    let dir = scratch("bvp-stationarity");
    runs(&dir);
    let st = |file: &str| -> f64 {
        let o = nonholo_in(
            &dir,
            &["bvp", "--stationarity-of", file, "--nodes", "201", "--json"],
        );
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&out(&o)).unwrap();
        assert_eq!(v["schema"], "nonholo.stationarity/1");
        v["max"].as_f64().unwrap()
    };
    let (c, b) = (st("vakonomic.json"), st("chetaev.json"));
    assert!(c < 1e-2 && b > 0.5, "C {c}, B {b}");
}

/// Refusals name the flag or the file and write nothing; a solve that
/// fails exits 1 with Newton's account.
#[test]
fn bvp_refuses_bad_input() {
    let dir = scratch("bvp-refusals");
    runs(&dir);
    let refused = |args: &[&str], says: &str| {
        let o = nonholo_in(&dir, args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{args:?}: {}", stderr(&o));
    };
    refused(&["bvp", "--scene", "sleigh-incline"], "--t-end");
    refused(
        &[
            "bvp",
            "--scene",
            "appell-hamel",
            "--formulation",
            "embedding",
            "--t-end",
            "1",
        ],
        "--dependent",
    );
    refused(
        &[
            "bvp",
            "--ends-from",
            "vakonomic.json",
            "--formulation",
            "chetaev",
        ],
        "no boundary-value form",
    );
    refused(
        &["bvp", "--ends-from", "vakonomic.json", "--ends", "natural"],
        "--ends: `natural` does not apply to formulation vakonomic",
    );
    // Dependent coordinates: one per nonholonomic constraint, each once,
    // the flag that is wrong named.
    for (dependent, says) in [
        (
            &["x", "y"][..],
            "--dependent: 2 dependent coordinates given (x, y)",
        ),
        (&["y", "y"][..], "--dependent: `y` is named twice"),
    ] {
        let mut args = vec![
            "bvp",
            "--scene",
            "sleigh-incline",
            "--formulation",
            "embedding",
            "--t-end",
            "1",
        ];
        for d in dependent {
            args.extend(["--dependent", d]);
        }
        refused(&args, says);
    }
    refused(
        &[
            "bvp",
            "--ends-from",
            "vakonomic.json",
            "--map-form",
            "explicit",
        ],
        "--map-form: a map form belongs to formulation embedding",
    );
    refused(
        &["bvp", "--ends-from", "vakonomic.json", "--t-end", "0.5021"],
        "not one of its output times",
    );
    refused(
        &["bvp", "--ends-from", "vakonomic.json", "--nodes", "2"],
        "--nodes",
    );
    refused(
        &[
            "bvp",
            "--ends-from",
            "vakonomic.json",
            "--scene",
            "rolling-disk",
        ],
        "is a run of scene sleigh-incline",
    );
    refused(&["bvp", "--ends-from", "missing.json"], "missing.json");
    refused(
        &[
            "bvp",
            "--scene",
            "sleigh-incline",
            "--t-end",
            "1",
            "--q0",
            "x=0",
            "--q0",
            "y=0",
            "--q1",
            "x=1",
            "--q1",
            "y=0",
            "--q1",
            "phi=0",
        ],
        "no value for `phi`",
    );
    refused(
        &[
            "bvp",
            "--ends-from",
            "vakonomic.json",
            "--formulation",
            "embedding",
            "--ends",
            "full",
            "--q0",
            "x=1",
        ],
        "the end data come from",
    );
    // The ends violate the map at t1: refused with the residual.
    let o = nonholo_in(
        &dir,
        &[
            "bvp",
            "--scene",
            "sleigh-incline",
            "--formulation",
            "embedding",
            "--ends",
            "full",
            "--t-end",
            "1",
            "--q0",
            "x=0",
            "--q0",
            "y=0",
            "--q0",
            "phi=0",
            "--q1",
            "x=1",
            "--q1",
            "y=0",
            "--q1",
            "phi=0.5",
            "--qd0",
            "x_dot=1",
            "--qd0",
            "y_dot=0",
            "--qd0",
            "phi_dot=0",
            "--qd1",
            "x_dot=1",
            "--qd1",
            "y_dot=0",
            "--qd1",
            "phi_dot=0",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("inconsistent end conditions at t = 1"),
        "{}",
        stderr(&o)
    );
    // Too large for the memory allowed: refused before anything is built.
    let o = nonholo_in(
        &dir,
        &[
            "bvp",
            "--ends-from",
            "vakonomic.json",
            "--nodes",
            "20000001",
            "--max-memory",
            "0.5",
        ],
    );
    assert_ne!(o.status.code(), Some(0));
    assert!(stderr(&o).contains("more than the limit"), "{}", stderr(&o));
    // Newton cannot converge in one iteration: exit 1, nothing written.
    let o = nonholo_in(
        &dir,
        &[
            "bvp",
            "--ends-from",
            "vakonomic.json",
            "--max-iter",
            "1",
            "--out",
            "never.json",
        ],
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("did not converge in 1 iterations"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.join("never.json").exists());
}

/// A small bvp experiment: the tables, figures and page, and its [bvp]
/// table checked at load (unknown labels, grids that do not fit a horizon).
#[test]
fn bvp_experiment_runs_and_refuses_inconsistent_tables() {
    let dir = scratch("bvp-experiment");
    let body = |bvp: &str| {
        format!(
            r#"[experiment]
name = "bvp-small"
kind = "bvp"
title = "t"
claim = "c"
scene = "rolling-disk"

[init]
theta = 0.4
omega_theta = 0.5
omega_psi = 1.0

[[formulation]]
label = "C"
formulation = "vakonomic"
rtol = 1e-12
atol = 1e-12
init = {{ lambda1 = 0.0, lambda2 = 0.3 }}

[[formulation]]
label = "B"
formulation = "chetaev"

{bvp}
"#
        )
    };
    let good = r#"[bvp]
ends_from = "C"
h = [0.05, 0.025, 0.0125]
horizons = [0.5, 1.0]
start = "line"
stationarity = ["B", "C"]
stationarity_under = ["Cb"]

[[bvp.line]]
label = "Af"
formulation = "embedding"
dependent = ["x", "y"]

[[bvp.line]]
label = "Cb"
formulation = "vakonomic"
"#;
    let file = experiment(&dir, "bvp-small", &body(good));
    let o = nonholo_in(&dir, &["experiment", &file]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.join("results/bvp-small");
    for f in [
        "bvp.json",
        "solves.csv",
        "ivp.csv",
        "stationarity.csv",
        "horizons.csv",
        "summary.json",
        "index.html",
        "plots/convergence-p0.png",
        "plots/newton-p0.png",
        "plots/horizons-p0.png",
        "plots/paths-p0.svg",
    ] {
        assert!(res.join(f).is_file(), "{f}");
    }
    assert!(bad_numbers(&res).is_empty(), "{:?}", bad_numbers(&res));
    let solves = csv_rows(&res.join("solves.csv"));
    assert_eq!(solves.len(), 2 * 3 * 2);
    // C's problem with C's ends: order 2 against C.
    let orders: Vec<f64> = solves
        .iter()
        .filter(|r| r["label"] == "Cb" && !r["order"].is_empty())
        .map(|r| r["order"].parse().unwrap())
        .collect();
    assert!(
        !orders.is_empty() && orders.iter().all(|o| (o - 2.0).abs() < 0.1),
        "{orders:?}"
    );
    assert_eq!(csv_rows(&res.join("stationarity.csv")).len(), 2 * 3 * 2);
    // A second run computes everything again; it agrees with the stored
    // result apart from wall times, so the stored one stays, to the byte
    // (`nonholo reproduce` on a fresh clone leaves it alone). `--force`
    // writes the new one.
    let stored = std::fs::read(res.join("bvp.json")).unwrap();
    let solves_csv = std::fs::read(res.join("solves.csv")).unwrap();
    let o = nonholo_in(&dir, &["experiment", &file]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("(1 reused)"), "{}", stderr(&o));
    assert!(std::fs::read(res.join("bvp.json")).unwrap() == stored);
    assert!(std::fs::read(res.join("solves.csv")).unwrap() == solves_csv);
    // A stored result that disagrees beyond its wall times is replaced.
    let mut edited: serde_json::Value = serde_json::from_slice(&stored).unwrap();
    let iterations = &mut edited["points"][0]["solves"][0]["iterations"];
    *iterations = (iterations.as_u64().unwrap() + 1).into();
    std::fs::write(res.join("bvp.json"), edited.to_string()).unwrap();
    let o = nonholo_in(&dir, &["experiment", &file]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("(0 reused)"), "{}", stderr(&o));
    let again: serde_json::Value =
        serde_json::from_slice(&std::fs::read(res.join("bvp.json")).unwrap()).unwrap();
    assert_ne!(again, edited, "a stored result that disagrees was kept");
    let o = nonholo_in(&dir, &["experiment", &file, "--force"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("(0 reused)"), "{}", stderr(&o));
    assert!(std::fs::read(res.join("bvp.json")).unwrap() != stored);
    // `nonholo plot` redraws from bvp.json.
    let o = nonholo_in(&dir, &["plot", &file]);
    assert!(o.status.success(), "{}", stderr(&o));
    for (bad, says) in [
        (
            good.replace("ends_from = \"C\"", "ends_from = \"X\""),
            "bvp.ends_from",
        ),
        (
            good.replace("h = [0.05, 0.025, 0.0125]", "h = [0.05, 0.03]"),
            "bvp.h",
        ),
        (
            good.replace("horizons = [0.5, 1.0]", "horizons = [0.5, 0.99]"),
            "bvp.horizons",
        ),
        (
            good.replace("label = \"Cb\"", "label = \"B\""),
            "used twice",
        ),
        (
            good.replace("dependent = [\"x\", \"y\"]", "dependent = [\"q\"]"),
            "not a coordinate",
        ),
        (
            good.replace("dependent = [\"x\", \"y\"]", "dependent = [\"x\"]"),
            "`bvp.line.dependent`: 1 dependent coordinates given (x), but rolling-disk has 2",
        ),
        (
            good.replace("start = \"line\"", "start = \"curve\""),
            "bvp.start",
        ),
        (
            good.replace(
                "stationarity_under = [\"Cb\"]",
                "stationarity_under = [\"C\"]",
            ),
            "bvp.stationarity_under",
        ),
        (
            good.replace(
                "[[bvp.line]]\nlabel = \"Af\"",
                "[[bvp.line]]\nbogus = 1\nlabel = \"Af\"",
            ),
            "bogus",
        ),
    ] {
        let file = experiment(&dir, "bvp-small", &body(&bad));
        let o = nonholo_in(&dir, &["experiment", &file]);
        assert_eq!(o.status.code(), Some(2), "{says}: {}", stderr(&o));
        assert!(stderr(&o).contains(says), "{says}: {}", stderr(&o));
    }
    // [bvp] in an experiment of another kind, and [time] in a bvp one.
    let other = body(good).replace("kind = \"bvp\"\n", "");
    let file = experiment(&dir, "bvp-small", &other);
    let o = nonholo_in(&dir, &["experiment", &file]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("[time]") || stderr(&o).contains("kind"),
        "{}",
        stderr(&o)
    );
    let timed = body(good).replace("[init]", "[time]\nt_end = 1\noutput_every = 0.1\n\n[init]");
    let file = experiment(&dir, "bvp-small", &timed);
    let o = nonholo_in(&dir, &["experiment", &file]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("horizons"), "{}", stderr(&o));
    // --shard is refused for a bvp experiment.
    let file = experiment(&dir, "bvp-small", &body(good));
    let o = nonholo_in(&dir, &["experiment", &file, "--shard", "1/2"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("bvp experiment"), "{}", stderr(&o));
}
