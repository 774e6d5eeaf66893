//! `nonholo simulate` and `nonholo scenes` as a user runs them: the issue's
//! command line, both output formats, and every bad-input case with its message.

use std::path::PathBuf;
use std::process::{Command, Output};

fn nonholo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_nonholo"))
        .args(args)
        .output()
        .expect("nonholo runs")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("nonholo-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

const ISSUE_COMMAND: &[&str] = &[
    "simulate",
    "--scene",
    "sleigh-incline",
    "--formulation",
    "chetaev",
    "--param",
    "a=0.4",
    "--param",
    "alpha=0.3",
    "--param",
    "potential=com",
    "--init",
    "x=0",
    "--init",
    "y=0",
    "--init",
    "phi=0.2",
    "--init",
    "u=2",
    "--init",
    "omega=0.7",
    "--t-end",
    "20",
    "--output-every",
    "1",
    "--integrator",
    "dop853",
    "--rtol",
    "1e-12",
    "--atol",
    "1e-12",
];

fn with(extra: &[&str]) -> Vec<String> {
    ISSUE_COMMAND
        .iter()
        .chain(extra)
        .map(|s| s.to_string())
        .collect()
}

fn run(args: &[String]) -> Output {
    let a: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
    nonholo(&a)
}

#[test]
fn issue_command_writes_json_with_the_schema() {
    let dir = tmpdir("json");
    let out = dir.join("run.json");
    let o = run(&with(&["--out", out.to_str().unwrap()]));
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(j["schema"], "nonholo.run/1");
    assert_eq!(j["scene"], "sleigh-incline");
    assert_eq!(j["formulation"], "chetaev");
    assert_eq!(j["integrator"]["method"], "dop853");
    assert_eq!(j["integrator"]["rtol"], 1e-12);
    assert_eq!(j["params"]["a"], 0.4);
    assert_eq!(j["params"]["potential"], "com");
    assert_eq!(j["params"]["m"], 1.0, "defaults are resolved too");
    assert_eq!(j["options"]["stab"], "none");
    assert_eq!(j["init"]["q"], serde_json::json!([0.0, 0.0, 0.2]));
    let qd0 = j["init"]["q_dot"].as_array().unwrap();
    assert!((qd0[0].as_f64().unwrap() - 2.0 * 0.2f64.cos()).abs() < 1e-15);
    assert_eq!(j["coordinates"], serde_json::json!(["x", "y", "phi"]));
    assert_eq!(j["t"].as_array().unwrap().len(), 21);
    assert_eq!(j["t"][20], 20.0);
    assert_eq!(j["q"].as_array().unwrap().len(), 21);
    assert_eq!(j["q"][0].as_array().unwrap().len(), 3);
    assert_eq!(j["q_dot"].as_array().unwrap().len(), 21);
    assert_eq!(j["lambda"][0].as_array().unwrap().len(), 1);
    assert!(j.get("nu").is_none());
    let d = &j["diagnostics"];
    assert!(d["constraint_residual_max"].as_f64().unwrap() < 1e-11);
    assert!(d["energy_drift_max"].as_f64().unwrap() < 1e-8);
    assert!(d["energy_initial"].is_number());
    for k in [
        "steps",
        "rejected_steps",
        "rhs_evals",
        "jacobian_evals",
        "wall_time_s",
    ] {
        assert!(j["stats"][k].is_number(), "stats.{k}");
    }
    assert_eq!(j["status"], "completed");
    assert!(j["error"].is_null());
    // Nothing left behind but the result.
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 1, "{names:?}");
}

#[test]
fn issue_command_writes_csv() {
    let dir = tmpdir("csv");
    let out = dir.join("run.csv");
    let o = run(&with(&["--out", out.to_str().unwrap()]));
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "t,x,y,phi,x_dot,y_dot,phi_dot,lambda");
    assert_eq!(lines.len(), 22);
    assert!(lines[1].starts_with("0,0,0,0.2,"));
    assert!(lines[21].starts_with("20,"));
}

#[test]
fn summary_without_out() {
    let o = run(&with(&[]));
    assert!(o.status.success());
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        s.contains("status: completed") && s.contains("phi_dot") && s.contains("lambda"),
        "{s}"
    );
}

fn fails_with(args: &[&str], code: i32, needles: &[&str]) {
    let o = nonholo(args);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(code), "{args:?}: {e}");
    for n in needles {
        assert!(e.contains(n), "{args:?}: `{n}` not in: {e}");
    }
    assert!(!e.contains("panicked"), "{e}");
}

#[test]
fn unknown_names_list_the_valid_ones() {
    fails_with(
        &["simulate", "--scene", "sled"],
        2,
        &[
            "unknown scene `sled`",
            "sleigh-incline, rolling-disk, appell-hamel, pendulum",
        ],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--formulation",
            "lagrange",
        ],
        2,
        &["unknown formulation `lagrange`", "chetaev"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--param", "mass=2"],
        2,
        &["unknown parameter `mass`", "m, J, a, g, alpha, potential"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--init", "theta=1"],
        2,
        &[
            "unknown initial value `theta`",
            "x, y, phi, x_dot, y_dot, phi_dot, u, omega",
        ],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--option",
            "stabilisation=none",
        ],
        2,
        &[
            "`stabilisation`",
            "stab, baumgarte_alpha, baumgarte_beta, singular_tol",
        ],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--integrator",
            "euler",
        ],
        2,
        &["unknown integrator `euler`", "rk4, dopri5, dop853"],
    );
}

#[test]
fn values_that_do_not_parse_or_are_out_of_range() {
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--param", "a=abc"],
        2,
        &["parameter `a`", "`abc`", "real number"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--param",
            "alpha=2",
        ],
        2,
        &["parameter `alpha` = 2", "[0, 1.5707963267948966)"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--param", "m=-1"],
        2,
        &["parameter `m` = -1", "(0, inf)"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--param",
            "potential=gravity",
        ],
        2,
        &["`potential`", "{paper, com}"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--param",
            "J=0.1",
            "--param",
            "a=0.5",
        ],
        2,
        &["J = 0.1, a = 0.5 violate J > a² = 0.25"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--init", "u=fast"],
        2,
        &["initial value `u`", "`fast`"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--option",
            "stab=always",
        ],
        2,
        &["`stab`", "{none, baumgarte, projection}"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--param", "a"],
        2,
        &["--param expects NAME=VALUE, got `a`"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--rtol", "-1"],
        2,
        &["--rtol", "positive"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--t-end", "0"],
        2,
        &["--t-end"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--integrator",
            "rk4",
        ],
        2,
        &["give --step"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--out", "run.txt"],
        2,
        &[".json or .csv"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--init",
            "u=1",
            "--init",
            "x_dot=1",
        ],
        2,
        &["either as", "not both"],
    );
}

#[test]
fn inconsistent_velocities_are_refused_or_projected() {
    let base = [
        "simulate",
        "--scene",
        "sleigh-incline",
        "--init",
        "phi=0.2",
        "--init",
        "x_dot=1",
        "--init",
        "y_dot=0",
        "--init",
        "phi_dot=0.5",
        "--t-end",
        "1",
    ];
    // g = ẏ cos φ − ẋ sin φ = −sin 0.2.
    fails_with(
        &base,
        2,
        &[
            "violate the constraints",
            "ẏ cos φ − ẋ sin φ = 0: residual -1.987e-1",
            "--project-init",
        ],
    );
    let dir = tmpdir("project");
    let out = dir.join("p.json");
    let mut args = base.to_vec();
    args.extend(["--project-init", "--out", out.to_str().unwrap()]);
    let o = nonholo(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("--project-init moved the initial data"),
        "{}",
        stderr(&o)
    );
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    let p = &j["init"]["projection"];
    assert_eq!(p["q_dot_before"], serde_json::json!([1.0, 0.0, 0.5]));
    assert!(p["velocity_residual_after"].as_f64().unwrap() < 1e-14);
    // M-nearest for the sleigh (a = 0.4): moves (ẋ, ẏ) and φ̇.
    let qd = j["init"]["q_dot"].as_array().unwrap();
    let (xd, yd) = (qd[0].as_f64().unwrap(), qd[1].as_f64().unwrap());
    assert!((yd * 0.2f64.cos() - xd * 0.2f64.sin()).abs() < 1e-14);
}

#[test]
fn singularity_stops_with_time_and_reason_and_no_file() {
    let dir = tmpdir("singular");
    let out = dir.join("ah.json");
    let args = [
        "simulate",
        "--scene",
        "appell-hamel",
        "--param",
        "c=-0.5",
        "--init",
        "rho=2",
        "--t-end",
        "3",
        "--out",
        out.to_str().unwrap(),
    ];
    // t* = ρ0 (1 + c²)/(|c| g) = 0.50968...
    fails_with(
        &args,
        1,
        &["at t = 0.5096", "horizontal speed", "no file written"],
    );
    assert!(!out.exists());
    let mut keep = args.to_vec();
    keep.push("--keep-partial");
    let o = nonholo(&keep);
    assert_eq!(o.status.code(), Some(1));
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap();
    assert_eq!(j["status"], "failed");
    assert!((j["error"]["t"].as_f64().unwrap() - 0.509683995922528).abs() < 1e-6);
    assert!(j["t"].as_array().unwrap().last().unwrap().as_f64().unwrap() < 0.5097);
}

#[test]
fn overflow_is_an_error_not_nan_in_a_file() {
    let dir = tmpdir("overflow");
    let out = dir.join("o.json");
    std::fs::write(&out, "previous").unwrap();
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--param",
            "g=1e307",
            "--param",
            "alpha=1.5",
            "--t-end",
            "100",
            "--out",
            out.to_str().unwrap(),
        ],
        1,
        &["at t = "],
    );
    // The previous file is untouched, and no temporary is left behind.
    assert_eq!(std::fs::read_to_string(&out).unwrap(), "previous");
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
}

#[test]
fn scenes_lists_coordinates_parameters_and_formulations() {
    let o = nonholo(&["scenes"]);
    assert!(o.status.success());
    let s = String::from_utf8_lossy(&o.stdout);
    for needle in [
        "sleigh-incline",
        "rolling-disk",
        "appell-hamel",
        "pendulum",
        "alpha",
        "[rad]",
        "default 0.3",
        "[0, 1.5707963267948966)",
        "B chetaev: applies",
        "φ = atan2(ẏ, ẋ)",
    ] {
        assert!(s.contains(needle), "`{needle}` missing from:\n{s}");
    }
    let o = nonholo(&["scenes", "--json"]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j[0]["name"], "sleigh-incline");
    assert_eq!(j[0]["params"][4]["name"], "alpha");
    assert_eq!(j[0]["formulations"][0]["applicable"], true);
}

/// A review found B stepping straight over Appell–Hamel's stop at loose
/// tolerances (|v| never changes sign). With the signed guard and stages
/// refused beyond the singular set, every adaptive method and tolerance stops
/// at t* − singular_tol/|ρ̇| = 0.5096839934 (t* = ρ0 (1 + c²)/(|c| g)); a fixed
/// step stops at the start of the step that would cross, with that reason.
#[test]
fn singularity_is_not_stepped_over_at_loose_tolerances() {
    let base = [
        "simulate",
        "--scene",
        "appell-hamel",
        "--param",
        "c=-0.5",
        "--init",
        "rho=2",
        "--t-end",
        "3",
    ];
    for extra in [
        &["--rtol", "1e-3", "--atol", "1e-3"][..],
        &["--rtol", "1e-4", "--atol", "1e-4", "--integrator", "dopri5"][..],
        &["--integrator", "radau5", "--rtol", "1e-4", "--atol", "1e-4"][..],
    ] {
        let mut args = base.to_vec();
        args.extend(extra);
        fails_with(&args, 1, &["at t = 0.50968399337", "horizontal speed"]);
    }
    let mut args = base.to_vec();
    args.extend(["--integrator", "rk4", "--step", "0.05"]);
    fails_with(
        &args,
        1,
        &[
            "at t = 0.5:",
            "a stage crossed the singular set",
            "fixed step h = 5.000e-2",
        ],
    );
}

/// Units do not decide singularity or consistency: masses of 1e8, a 1000 m
/// pendulum, positions of 1e9 m.
#[test]
fn results_do_not_depend_on_units() {
    for m in ["1e8", "1e-8"] {
        let o = nonholo(&[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--param",
            &format!("m={m}"),
            "--t-end",
            "2",
        ]);
        assert!(o.status.success(), "m = {m}: {}", stderr(&o));
    }
    for l in ["100", "1000"] {
        let o = nonholo(&[
            "simulate",
            "--scene",
            "pendulum",
            "--param",
            &format!("l={l}"),
            "--init",
            "omega=0.01",
            "--option",
            "stab=projection",
            "--t-end",
            "5",
            "--rtol",
            "1e-8",
            "--atol",
            "1e-8",
        ]);
        assert!(o.status.success(), "l = {l}: {}", stderr(&o));
        let o = nonholo(&[
            "simulate",
            "--scene",
            "pendulum",
            "--param",
            &format!("l={l}"),
            "--init",
            "x=1",
            "--project-init",
            "--t-end",
            "1",
        ]);
        assert!(o.status.success(), "l = {l} --project-init: {}", stderr(&o));
    }
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--init",
            "x=1e9",
            "--init",
            "phi=0",
            "--init",
            "x_dot=1",
            "--init",
            "y_dot=0.5",
            "--init",
            "phi_dot=0.3",
        ],
        2,
        &["violate the constraints", "distance 5.000e-1"],
    );
}

#[test]
fn limits_and_formats_are_enforced() {
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--rtol", "1e-20"],
        2,
        &["--rtol: 1e-20", "double precision"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--output-every",
            "1e-300",
        ],
        2,
        &["output points", "limit 1e6"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--out",
            "x.csv",
            "--keep-partial",
        ],
        2,
        &["--keep-partial needs a .json"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--param",
            "alpha=90deg",
        ],
        2,
        &["`alpha` = 90deg"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--param",
            "a=1e400",
        ],
        2,
        &["`a` = 1e400"],
    );
    fails_with(
        &["simulate", "--scene", "sleigh-incline", "--param", "a=x"],
        2,
        &["a real number in (-inf, inf)"],
    );
    let o = nonholo(&[
        "simulate",
        "--scene",
        "appell-hamel",
        "--init",
        "beta=45deg",
        "--t-end",
        "1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn csv_comes_with_its_metadata() {
    let dir = tmpdir("csvmeta");
    let out = dir.join("run.csv");
    let o = run(&with(&[
        "--out",
        out.to_str().unwrap(),
        "--option",
        "stab=projection",
    ]));
    assert!(o.status.success(), "{}", stderr(&o));
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("run.csv.meta.json")).unwrap()).unwrap();
    assert_eq!(meta["options"]["stab"], "projection");
    assert_eq!(meta["status"], "completed");
    assert!(meta.get("q").is_none() && meta["diagnostics"]["energy_initial"].is_number());
}

#[test]
fn a_closed_pipe_is_not_a_panic() {
    use std::process::Stdio;
    // The pipe's reader is gone before nonholo starts.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = Command::new(env!("CARGO_BIN_EXE_nonholo"))
        .arg("scenes")
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    // The listing did not arrive: an output error, named.
    assert_eq!(out.status.code(), Some(4), "{err}");
    assert!(err.contains("cannot write to stdout"), "{err}");
}

#[test]
fn embedding_applicability_and_integrator() {
    fails_with(
        &[
            "simulate",
            "--scene",
            "appell-hamel",
            "--formulation",
            "embedding",
        ],
        2,
        &["not applicable", "eq. (28)"],
    );
    // A has an explicit form too (q⁗ from the derivative array): DOP853 and
    // Radau IIA (implicit form) give the same motion.
    let dir = tmpdir("embedding-forms");
    let mut ends = Vec::new();
    for integrator in ["dop853", "radau5"] {
        let out = dir.join(format!("{integrator}.json"));
        let o = nonholo(&[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--formulation",
            "embedding",
            "--integrator",
            integrator,
            "--t-end",
            "0.85",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{integrator}: {}", stderr(&o));
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let last = j["q"].as_array().unwrap().last().unwrap().clone();
        ends.push([last[0].as_f64().unwrap(), last[1].as_f64().unwrap()]);
    }
    let d = (ends[0][0] - ends[1][0]).hypot(ends[0][1] - ends[1][1]);
    assert!(d < 1e-7, "explicit and implicit forms of A differ by {d:e}");
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--formulation",
            "embedding",
            "--integrator",
            "radau5",
            "--init",
            "lambda=0.5",
            "--init",
            "x_ddot=1",
        ],
        2,
        &["either as lambda", "not both"],
    );
    let o = nonholo(&["scenes"]);
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        s.contains("A embedding: applies") && s.contains("C vakonomic: applies"),
        "{s}"
    );
    assert!(
        s.contains("A embedding: not applicable — the scene provides no embedding map"),
        "{s}"
    );
}

/// A runs across the sleigh's reversals (docs/embedding.md §6): each
/// crossing is recorded in the run's JSON, and the motion stays on C's
/// (matched by λ0) through them.
#[test]
fn embedding_records_its_crossings_and_follows_c_through_them() {
    let dir = tmpdir("crossings");
    let mut runs = Vec::new();
    for f in ["embedding", "vakonomic"] {
        let out = dir.join(format!("{f}.json"));
        let o = nonholo(&[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--formulation",
            f,
            "--init",
            "lambda=0.5",
            "--t-end",
            "3",
            "--output-every",
            "0.25",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{f}: {}", stderr(&o));
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        runs.push(j);
    }
    let (a, c) = (&runs[0], &runs[1]);
    assert_eq!(c["crossings"], serde_json::json!([]));
    let crossings = a["crossings"].as_array().unwrap();
    // C's heading speed u = ẋ cos φ + ẏ sin φ changes sign between the 1 ms
    // samples at 1.179|1.180, 1.822|1.823, 2.305|2.306, 2.706|2.707 s: one
    // crossing each, at the singular instant.
    assert_eq!(crossings.len(), 4, "{crossings:?}");
    let mut last = 0.0;
    for (i, x) in crossings.iter().enumerate() {
        let f = |k: &str| x[k].as_f64().unwrap();
        assert_eq!(x["number"], i + 1);
        assert!(last <= f("t_stop") && f("t_stop") < f("t_singular"));
        assert!(f("t_singular") < f("t_resume"));
        assert!(f("gap_error") < 1e-8 && f("return_residual") < 1e-7, "{x}");
        assert!(f("restart_change") < 1e-12, "{x}");
        // The instant estimated before the crossing: inside the bracket, to
        // 0.1 ms.
        let lo = [1.179, 1.822, 2.305, 2.706][i];
        assert!(
            f("t_singular") > lo - 1e-4 && f("t_singular") < lo + 1.1e-3,
            "{x}"
        );
        last = f("t_resume");
    }
    let d = a["q"]
        .as_array()
        .unwrap()
        .iter()
        .zip(c["q"].as_array().unwrap())
        .map(|(p, r)| {
            let g = |v: &serde_json::Value, i: usize| v[i].as_f64().unwrap();
            (g(p, 0) - g(r, 0)).hypot(g(p, 1) - g(r, 1))
        })
        .fold(0.0, f64::max);
    assert!(d < 1e-8, "A and C differ by {d:e} m");
}

/// The realisations as the issue writes them: `visc` with `k`, `mass` with
/// `N` and `λ0`; their multiplier column; their options checked by name.
#[test]
fn realisations_run_from_the_command_line() {
    let dir = tmpdir("realise");
    let out = dir.join("visc.json");
    let o = nonholo(&[
        "simulate",
        "--scene",
        "sleigh-incline",
        "--formulation",
        "visc",
        "--option",
        "k=1e6",
        "--param",
        "a=0.4",
        "--init",
        "u=2",
        "--init",
        "omega=0.7",
        "--t-end",
        "2",
        "--integrator",
        "radau5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(j["formulation"], "visc");
    assert_eq!(j["options"]["k"], 1e6);
    assert!(j["lambda"].as_array().unwrap().len() > 10);
    // The violation is O(1/k): a few times 1e-6 for this motion.
    let r = j["diagnostics"]["constraint_residual_max"]
        .as_f64()
        .unwrap();
    assert!(r > 1e-7 && r < 1e-5, "{r}");

    let out = dir.join("mass.json");
    let o = nonholo(&[
        "simulate",
        "--scene",
        "sleigh-incline",
        "--formulation",
        "mass",
        "--option",
        "N=1e4",
        "--init",
        "lambda=0.5",
        "--init",
        "u=2",
        "--t-end",
        "0.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(j["lambda"][0][0], 0.5);
    assert_eq!(j["options"]["form"], "compliance");

    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--formulation",
            "visc",
            "--option",
            "k=-1",
        ],
        2,
        &["`k`", "-1", "(0, inf)"],
    );
    fails_with(
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--formulation",
            "mass",
            "--option",
            "form=soft",
        ],
        2,
        &["`form`", "compliance", "direct"],
    );
    fails_with(
        &["simulate", "--scene", "pendulum", "--formulation", "visc"],
        2,
        &["not applicable", "no nonholonomic constraints"],
    );
}

/// `simulate` on `visc` at k = 1e6 by radau5 with `--radau-dense NAME`.
fn visc_radau(dense: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "simulate",
        "--scene",
        "sleigh-incline",
        "--formulation",
        "visc",
        "--option",
        "k=1e6",
        "--integrator",
        "radau5",
        "--t-end",
        "2",
        "--rtol",
        "1e-8",
        "--radau-dense",
        dense,
    ];
    args.extend(extra);
    nonholo(&args)
}

/// `--radau-dense`: the record names the extension (`auto`, the default,
/// included), and the runs take the same steps (the extension changes no
/// step); `auto` is the Hermite extension on this ODE form, sample for
/// sample.
#[test]
fn radau_dense_is_recorded_and_changes_no_step() {
    let dir = tmpdir("radau-dense");
    let names = ["collocation", "hermite", "auto"];
    let runs: Vec<serde_json::Value> = names
        .iter()
        .map(|dense| {
            let out = dir.join(format!("{dense}.json"));
            let o = visc_radau(dense, &["--out", out.to_str().unwrap()]);
            assert!(o.status.success(), "{}", stderr(&o));
            serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap()
        })
        .collect();
    for (run, name) in runs.iter().zip(names) {
        assert_eq!(run["integrator"]["radau5"]["dense_output"], name);
        for counter in ["steps", "rhs_evals", "jacobian_evals"] {
            assert_eq!(
                runs[0]["stats"][counter], run["stats"][counter],
                "{counter}"
            );
        }
    }
    assert_eq!(runs[1]["q"], runs[2]["q"]);
    assert_ne!(runs[0]["q"], runs[1]["q"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--radau-jacobian-reuse`: recorded as RADAU5's `jacobian_reuse`; a
/// laxer threshold keeps Jacobians longer (fewer evaluations on this
/// stiff run); a value at or above 1, or not finite, is refused naming the
/// flag.
#[test]
fn radau_jacobian_reuse_is_recorded_and_validated() {
    let dir = tmpdir("radau-reuse");
    let runs: Vec<serde_json::Value> = ["0.001", "0.1"]
        .iter()
        .map(|theta| {
            let out = dir.join(format!("{theta}.json"));
            let o = visc_radau(
                "auto",
                &[
                    "--radau-jacobian-reuse",
                    theta,
                    "--out",
                    out.to_str().unwrap(),
                ],
            );
            assert!(o.status.success(), "{}", stderr(&o));
            serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap()
        })
        .collect();
    assert_eq!(runs[0]["integrator"]["radau5"]["jacobian_reuse"], 0.001);
    assert_eq!(runs[1]["integrator"]["radau5"]["jacobian_reuse"], 0.1);
    let jac = |r: &serde_json::Value| r["stats"]["jacobian_evals"].as_u64().unwrap();
    assert!(
        jac(&runs[1]) < jac(&runs[0]),
        "{} {}",
        jac(&runs[1]),
        jac(&runs[0])
    );
    for bad in ["1", "inf", "NaN"] {
        let o = visc_radau("auto", &["--radau-jacobian-reuse", bad]);
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(
            e.contains("--radau-jacobian-reuse") && e.contains("below 1"),
            "{e}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--radau-newton-tol`: recorded as RADAU5's `newton_tol` (absent, the
/// record holds no value: the default depends on the tolerance); a tighter
/// stopping test costs Newton iterations (right-hand sides) on this stiff run; a value outside
/// (0, 1) is refused naming the flag.
#[test]
fn radau_newton_tol_is_recorded_and_validated() {
    let dir = tmpdir("radau-newton-tol");
    let runs: Vec<serde_json::Value> = [None, Some("1e-6")]
        .iter()
        .map(|tol| {
            let out = dir.join(format!("{}.json", tol.unwrap_or("default")));
            let mut args = vec!["--out", out.to_str().unwrap()];
            if let Some(t) = tol {
                args.extend(["--radau-newton-tol", t]);
            }
            let o = visc_radau("auto", &args);
            assert!(o.status.success(), "{}", stderr(&o));
            serde_json::from_slice(&std::fs::read(&out).unwrap()).unwrap()
        })
        .collect();
    assert!(runs[0]["integrator"]["radau5"]["newton_tol"].is_null());
    assert_eq!(runs[1]["integrator"]["radau5"]["newton_tol"], 1e-6);
    let it = |r: &serde_json::Value| r["stats"]["rhs_evals"].as_u64().unwrap();
    assert!(
        it(&runs[1]) > it(&runs[0]),
        "{} {}",
        it(&runs[1]),
        it(&runs[0])
    );
    for bad in ["0", "1", "-1e-6", "inf", "NaN"] {
        let o = visc_radau("auto", &["--radau-newton-tol", bad]);
        assert!(!o.status.success());
        let e = stderr(&o);
        assert!(
            e.contains("--radau-newton-tol") && e.contains("between 0 and 1"),
            "{e}"
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An unknown `--radau-dense` is refused naming the flag; A's implicit form
/// (a DAE under radau5) refuses the Hermite extension with the reason.
#[test]
fn radau_dense_refuses_bad_names_and_implicit_forms() {
    let o = visc_radau("cubic", &[]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(
        e.contains("--radau-dense") && e.contains("auto, collocation, hermite"),
        "{e}"
    );
    let o = nonholo(&[
        "simulate",
        "--scene",
        "sleigh-incline",
        "--formulation",
        "embedding",
        "--integrator",
        "radau5",
        "--radau-dense",
        "hermite",
        "--t-end",
        "0.5",
    ]);
    // Refused with the input (exit 2), before anything runs.
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o) + &String::from_utf8_lossy(&o.stdout);
    assert!(
        e.contains("radau_dense = hermite") && e.contains("implicit form"),
        "{e}"
    );
    // Radau IIA's settings with another integrator: refused, not ignored.
    for (flag, value) in [
        ("--radau-dense", "hermite"),
        ("--radau-newton", "full"),
        ("--radau-jacobian-reuse", "0.1"),
        ("--radau-newton-tol", "1e-3"),
    ] {
        let o = nonholo(&[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--integrator",
            "dop853",
            flag,
            value,
            "--t-end",
            "0.5",
        ]);
        assert_eq!(o.status.code(), Some(2), "{flag}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(&format!(
                "{flag}: a setting of --integrator radau5, not of dop853"
            )),
            "{}",
            stderr(&o)
        );
    }
}

/// `NONHOLO_NATIVE=0` (docs/cli.md) runs the programs interpreted, and the
/// trajectory is the native run's, digit for digit: B and C, each by
/// DOP853 (right-hand sides over `f64`) and by Radau IIA (Jacobians over
/// `Dual64` as well). The output does not show whether the variable took
/// effect; `nonholo_core::jit`'s tests check how it is read, and
/// `tests/native.rs` compares the two paths within one process.
#[test]
fn native_code_off_changes_no_digit() {
    let dir = tmpdir("native");
    for formulation in ["chetaev", "vakonomic"] {
        for integrator in ["dop853", "radau5"] {
            let mut args: Vec<String> = ISSUE_COMMAND.iter().map(|s| s.to_string()).collect();
            for (flag, value) in [("--formulation", formulation), ("--integrator", integrator)] {
                let at = args.iter().position(|a| a == flag).unwrap();
                args[at + 1] = value.to_string();
            }
            if formulation == "vakonomic" {
                args.extend(["--init".to_string(), "lambda=0.5".to_string()]);
            }
            let texts: Vec<String> = ["1", "0"]
                .iter()
                .map(|native| {
                    let out = dir.join(format!("{formulation}-{integrator}-{native}.csv"));
                    let mut a = args.clone();
                    a.extend(["--out".to_string(), out.to_str().unwrap().to_string()]);
                    let o = Command::new(env!("CARGO_BIN_EXE_nonholo"))
                        .args(&a)
                        .env("NONHOLO_NATIVE", native)
                        .output()
                        .expect("nonholo runs");
                    assert!(o.status.success(), "{}", stderr(&o));
                    std::fs::read_to_string(&out).unwrap()
                })
                .collect();
            assert!(texts[0].lines().count() == 22, "{}", texts[0]);
            assert_eq!(texts[0], texts[1], "{formulation} by {integrator}");
        }
    }
}
