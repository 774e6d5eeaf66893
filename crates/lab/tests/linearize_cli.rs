//! `nonholo linearize` and experiments of kind `stability` from the command
//! line: what they print and write, and what they refuse (status 2, the
//! message naming the field or the moving component).

mod common;

use common::*;

fn out(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The bicycle at 5 m/s under B: JSON with the essential components, the
/// cyclic coordinates and Table 2's eigenvalues (Meijaard et al. 2007).
#[test]
fn linearize_prints_the_benchmark_eigenvalues_as_json() {
    let o = nonholo(&[
        "linearize",
        "--scene",
        "bicycle",
        "--steady",
        "v=5",
        "--independent",
        "phi_dot",
        "--independent",
        "delta_dot",
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&out(&o)).unwrap();
    assert_eq!(v["schema"], "nonholo.linearisation/1");
    let essential: Vec<&str> = v["essential"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s.as_str().unwrap())
        .collect();
    assert!(
        essential.starts_with(&["phi", "delta", "phi_dot", "delta_dot"]),
        "{essential:?}"
    );
    let modes = v["modes"].as_array().unwrap();
    let has = |re: f64, im: f64| {
        modes.iter().any(|m| {
            (m["re"].as_f64().unwrap() - re).abs() < 1e-10
                && (m["im"].as_f64().unwrap() - im).abs() < 1e-10
        })
    };
    assert!(has(-0.32286642900409, 0.0));
    assert!(has(-0.77534188219585, 4.46486771378823));
    assert!(has(-14.07838969279822, 0.0));
}

/// Text output names the cyclic coordinates; a scene with none says so.
#[test]
fn linearize_text_states_the_reduction() {
    let o = nonholo(&[
        "linearize",
        "--scene",
        "sleigh-incline",
        "--param",
        "alpha=0",
        "--steady",
        "u=1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = out(&o);
    assert!(text.contains("cyclic (quotiented out)"), "{text}");
    assert!(text.contains("-4.00000000000000e-1"), "{text}");
    let o = nonholo(&[
        "linearize",
        "--scene",
        "pendulum",
        "--steady",
        "x=0",
        "--steady",
        "y=-1",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        out(&o).contains("no coordinate is cyclic here"),
        "{}",
        out(&o)
    );
}

/// Refused with status 2: a state that is not steady (naming the moving
/// component), an unknown component, formulation A, a bad tolerance.
#[test]
fn linearize_refuses_what_it_cannot_do() {
    for (args, needle) in [
        (
            vec!["linearize", "--scene", "sleigh-incline", "--steady", "u=1"],
            "not a steady motion: `x_dot` changes",
        ),
        (
            vec![
                "linearize",
                "--scene",
                "bicycle",
                "--steady",
                "v=5",
                "--independent",
                "nope",
            ],
            "unknown state component `nope`",
        ),
        (
            vec![
                "linearize",
                "--scene",
                "sleigh-incline",
                "--formulation",
                "embedding",
                "--steady",
                "u=1",
            ],
            "begins with (q, q̇)",
        ),
        (
            vec![
                "linearize",
                "--scene",
                "bicycle",
                "--steady",
                "v=5",
                "--steady-tol",
                "-1",
            ],
            "--steady-tol",
        ),
        (
            vec![
                "linearize",
                "--scene",
                "bicycle",
                "--steady",
                "v=5",
                "--param",
                "IBxz=10",
            ],
            "positive definite",
        ),
        // The adapted form of visc: the message names the form that works.
        (
            vec![
                "linearize",
                "--scene",
                "sleigh-incline",
                "--formulation",
                "visc",
                "--steady",
                "u=1",
            ],
            "--option form=cartesian",
        ),
        (
            vec![
                "linearize",
                "--scene",
                "bicycle",
                "--steady",
                "v=5",
                "--independent",
                "phi_dot",
                "--independent",
                "phi_dot",
            ],
            "--independent: `phi_dot` is given twice",
        ),
        // A steady motion off the constraints: no --project-init to offer.
        (
            vec!["linearize", "--scene", "pendulum", "--steady", "x=0.5"],
            "--steady: the steady motion's positions violate the holonomic constraints",
        ),
    ] {
        let o = nonholo(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{args:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("--project-init"), "{}", stderr(&o));
    }
}

/// A stability experiment over a scene parameter: the files it writes, the
/// crossings it locates, and a file mixing in compare-only tables refused.
#[test]
fn stability_experiment_writes_its_tables_and_refuses_foreign_tables() {
    let dir = scratch("stability");
    let file = experiment(
        &dir,
        "sleigh-a",
        r#"
[experiment]
name = "sleigh-a"
kind = "stability"
title = "t"
claim = "c"
scene = "sleigh-incline"

[params]
alpha = 0.0

[init]
u = 1.0

[[formulation]]
label = "B"
formulation = "chetaev"

[stability]
over = "param.a"
range = [-0.5, 0.5]
samples = 11
"#,
    );
    let o = nonholo_in(&dir, &["experiment", &file, "--threads", "2"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let res = dir.join("results/sleigh-a");
    for f in [
        "eigenvalues.csv",
        "samples.csv",
        "crossings.csv",
        "stability.json",
        "summary.json",
        "manifest.json",
        "index.html",
        "plots/eigenvalues-re.png",
    ] {
        assert!(res.join(f).is_file(), "{f}");
    }
    // −a u0/J changes sign at a = 0: one real crossing, from 1 unstable to none.
    let crossings = csv_rows(&res.join("crossings.csv"));
    assert_eq!(crossings.len(), 1, "{crossings:?}");
    let c = &crossings[0];
    assert!(c["param.a"].parse::<f64>().unwrap().abs() < 1e-12, "{c:?}");
    assert_eq!(
        (
            c["unstable_below"].as_str(),
            c["unstable_above"].as_str(),
            c["mode"].as_str()
        ),
        ("1", "0", "real")
    );
    let o = nonholo_in(&dir, &["plot", &file]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bad = experiment(
        &dir,
        "bad",
        r#"
[experiment]
name = "bad"
kind = "stability"
title = "t"
claim = "c"
scene = "sleigh-incline"

[time]
t_end = 1.0
output_every = 0.1

[[formulation]]
label = "B"
formulation = "chetaev"

[stability]
over = "param.a"
range = [0.0, 1.0]
samples = 3
"#,
    );
    let o = nonholo_in(&dir, &["experiment", &bad]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("[time] has no meaning in a stability experiment"),
        "{}",
        stderr(&o)
    );
    // Finite ends whose width overflows: refused before anything is written.
    let wide = std::fs::read_to_string(dir.join(&file))
        .unwrap()
        .replace("name = \"sleigh-a\"", "name = \"wide\"")
        .replace("range = [-0.5, 0.5]", "range = [-1e308, 1e308]");
    let wide = experiment(&dir, "wide", &wide);
    let o = nonholo_in(&dir, &["experiment", &wide]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("stability.range") && stderr(&o).contains("finite width"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.join("results/wide").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// The viscous realisation (Cartesian form), linearised without reduction
/// about the horizontal sleigh's straight motion, has B's turning
/// eigenvalue −a u0/J = −0.4 1/s up to O(1/k), plus a fast one near −k/m
/// that damps the constraint violation.
#[test]
fn viscous_realisation_approaches_b_eigenvalue_like_one_over_k() {
    let mut errors = Vec::new();
    for k in ["100", "10000"] {
        let o = nonholo(&[
            "linearize",
            "--scene",
            "sleigh-incline",
            "--param",
            "alpha=0",
            "--steady",
            "u=1",
            "--formulation",
            "visc",
            "--option",
            "form=cartesian",
            "--option",
            &format!("k={k}"),
            "--json",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_str(&out(&o)).unwrap();
        let re: Vec<f64> = v["modes"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["re"].as_f64().unwrap())
            .collect();
        let turning = re
            .iter()
            .copied()
            .min_by(|a, b| (a + 0.4).abs().total_cmp(&(b + 0.4).abs()))
            .unwrap();
        let fastest = re.iter().copied().fold(f64::INFINITY, f64::min);
        assert!(fastest < -0.5 * k.parse::<f64>().unwrap(), "{re:?}");
        errors.push((turning + 0.4).abs());
    }
    // 100 times the gain, about 100 times closer.
    let ratio = errors[0] / errors[1];
    assert!((50.0..200.0).contains(&ratio), "{errors:?}");
}
