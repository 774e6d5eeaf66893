//! Inputs that used to hang or run far past their budgets (issue 10, items
//! 1 and 11), as the `nonholo` command line receives them: each ends within
//! its budget plus set-up, with a message naming the reason.

use std::process::Command;
use std::time::Instant;

/// Runs `nonholo simulate ARGS` and returns (exit code, stdout + stderr,
/// seconds).
fn simulate(args: &[&str]) -> (i32, String, f64) {
    let start = Instant::now();
    let out = Command::new(env!("CARGO_BIN_EXE_nonholo"))
        .arg("simulate")
        .args(args)
        .output()
        .expect("nonholo runs");
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (
        out.status.code().unwrap_or(-1),
        text,
        start.elapsed().as_secs_f64(),
    )
}

/// Item 1: A from zero speed sent nalgebra's SVD into an endless loop during
/// set-up, before any budget applied. Now refused at once, naming |r|.
#[test]
fn a_at_zero_speed_is_refused_at_once() {
    let (code, text, secs) = simulate(&[
        "--scene",
        "sleigh-incline",
        "--formulation",
        "embedding",
        "--init",
        "lambda=0",
        "--init",
        "u=0",
        "--t-end",
        "1.2",
        "--max-wall-time",
        "2",
        "--max-steps",
        "10",
    ]);
    assert_ne!(code, 0, "{text}");
    assert!(
        text.contains("within singular_tol") && text.contains("|r| = 0.000e0"),
        "{text}"
    );
    // A wall-clock bound only to catch a hang (the budget plus a second).
    assert!(secs < 3.0, "{secs} s");
}

/// Item 11: a fixed step that cannot cover the span within the step budget
/// is refused before the first step (it used to run for 265 s).
#[test]
fn a_fixed_step_beyond_the_step_budget_is_refused() {
    let (code, text, _) = simulate(&[
        "--scene",
        "sleigh-incline",
        "--integrator",
        "rk4",
        "--step",
        "1e-320",
    ]);
    assert_ne!(code, 0, "{text}");
    assert!(
        text.contains("more than the step budget max_steps"),
        "{text}"
    );
}

/// Item 11, and the messages of item 12: with a wall-time budget every one
/// of the slow cases ends within it plus a second, and says why.
#[test]
fn wall_time_budgets_bite() {
    for args in [
        &[
            "--formulation",
            "visc",
            "--option",
            "k=1e9",
            "--integrator",
            "dop853",
        ][..],
        &["--formulation", "chetaev", "--t-end", "1e308"],
        &["--formulation", "chetaev", "--init", "u=1e10"],
        &[
            "--formulation",
            "mass",
            "--option",
            "N=1e12",
            "--option",
            "form=direct",
            "--integrator",
            "radau5",
        ],
    ] {
        let mut all = vec!["--scene", "sleigh-incline", "--max-wall-time", "1"];
        all.extend_from_slice(args);
        let (code, text, secs) = simulate(&all);
        assert_ne!(code, 0, "{args:?}: {text}");
        assert!(
            text.contains("wall-time budget of 1 s used up"),
            "{args:?}: {text}"
        );
        assert!(secs < 2.5, "{args:?}: {secs} s");
    }
}

/// Item 12: appell-hamel with `c = 0` is regular at zero horizontal speed
/// (it used to fail with a NaN pivot), and `singular_tol` far above the
/// state's distance says so instead of claiming the set was reached.
#[test]
fn regular_constraints_and_huge_singular_tol_read_right() {
    let (code, text, _) = simulate(&[
        "--scene",
        "appell-hamel",
        "--param",
        "c=0",
        "--init",
        "rho=0",
        "--t-end",
        "1",
    ]);
    assert_eq!(code, 0, "{text}");
    let (code, text, _) = simulate(&[
        "--scene",
        "appell-hamel",
        "--option",
        "singular_tol=1e300",
        "--t-end",
        "1",
    ]);
    assert_ne!(code, 0, "{text}");
    assert!(
        text.contains("came within singular_tol = 1.0e300"),
        "{text}"
    );
}

/// Item 11: with `--stiff-stop`, the stiff case ends where the stiffness
/// test of DOP853 keeps firing (a few thousand steps in), naming radau5,
/// and the run's JSON records the setting.
#[test]
fn stiff_stop_ends_an_explicit_run_on_a_stiff_problem() {
    let dir = std::env::temp_dir().join(format!("nonholo-stiff-stop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("run.json");
    let (code, text, _) = simulate(&[
        "--scene",
        "sleigh-incline",
        "--formulation",
        "visc",
        "--option",
        "k=1e9",
        "--integrator",
        "dop853",
        "--stiff-stop",
        "--max-steps",
        "100000",
        "--keep-partial",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_ne!(code, 0, "{text}");
    assert!(
        text.contains("the problem is stiff for this explicit method") && text.contains("radau5"),
        "{text}"
    );
    let run: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(run["integrator"]["stiff_stop"], true);
    let steps = run["stats"]["steps"].as_u64().unwrap();
    assert!(steps < 10_000, "{steps} steps");
    std::fs::remove_dir_all(&dir).unwrap();
}
