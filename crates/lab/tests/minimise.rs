//! `[minimise]` against a closed form: on the vertical rolling disk C
//! reproduces B exactly for λ(0) = −m R ψ̇0 (cos θ0, sin θ0) (docs/figures.md,
//! disk-equivalence). With λ2(0) set to its value, the minimisation over
//! λ1(0) must find λ1 = −m R ψ̇0 cos θ0 and a distance at round-off level,
//! at every state.

mod common;

use common::{experiment, nonholo_in, scratch, stderr};

fn rows(path: &std::path::Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let h: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    r.records()
        .map(|x| {
            h.iter()
                .cloned()
                .zip(x.unwrap().iter().map(String::from))
                .collect()
        })
        .collect()
}

#[test]
fn minimisation_finds_the_multiplier_that_reproduces_b() {
    let root = scratch("minimise");
    let thetas = [0.0f64, 0.7, 2.5];
    // m = R = 1 by default and ψ̇0 = 1: λ = −(cos θ0, sin θ0).
    let lambda2: Vec<String> = thetas.iter().map(|t| format!("{:?}", -t.sin())).collect();
    let body = format!(
        r#"[experiment]
name = "min"
title = "minimise"
claim = "none"
scene = "rolling-disk"

[init]
omega_theta = 0.5
omega_psi = 1.0

[time]
t_end = 2.0
output_every = 0.05

[[formulation]]
label = "B"
formulation = "chetaev"
rtol = 1e-12
atol = 1e-12

[[formulation]]
label = "C"
formulation = "vakonomic"
rtol = 1e-12
atol = 1e-12

[sweep]
mode = "zip"
values = {{ "init.theta" = [{}], "C.init.lambda2" = [{}] }}

[measures]
reference = "B"

[minimise]
over = "C.init.lambda1"
range = [-2.0, 1.5]
samples = 36
refine = 1
label = "C"
"#,
        thetas.map(|t| format!("{t:?}")).join(", "),
        lambda2.join(", ")
    );
    let file = experiment(&root, "min", &body);
    let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let dir = root.join("results/min");
    let minima = rows(&dir.join("minima.csv"));
    assert_eq!(minima.len(), thetas.len());
    for (r, theta) in minima.iter().zip(thetas) {
        let best: f64 = r["best"].parse().unwrap();
        let distance: f64 = r["distance"].parse().unwrap();
        let grid: f64 = r["grid_distance"].parse().unwrap();
        assert!(
            (best + theta.cos()).abs() < 1e-6,
            "θ0 = {theta}: λ1 = {best}"
        );
        assert!(
            distance < 1e-6 && distance <= grid,
            "θ0 = {theta}: {distance} (grid {grid})"
        );
        assert_eq!(r["undefined"], "0");
        let evaluations: usize = r["evaluations"].parse().unwrap();
        assert!(evaluations > 36 && evaluations < 36 + 120, "{evaluations}");
    }
    // The sampled objective, the figures, the summary and the page.
    assert!(dir.join("minimise/0.csv").is_file());
    for f in ["plots/minimise.png", "plots/minimise-curve.png"] {
        assert!(dir.join(f).is_file(), "{f}");
    }
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap()).unwrap();
    assert!(summary["minima"]["smallest"]["distance"].as_f64().unwrap() < 1e-6);
    let page = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(page.contains("Minimisation over C.init.lambda1"));
    // `nonholo plot` redraws from the files.
    let o = nonholo_in(&root, &["plot", &file]);
    assert!(o.status.success(), "{}", stderr(&o));
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn bad_minimise_tables_name_the_key() {
    let root = scratch("minimise-bad");
    let base = |extra: &str| {
        format!(
            r#"[experiment]
name = "bad"
title = "t"
claim = "c"
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

[[formulation]]
label = "C"
formulation = "vakonomic"

[measures]
reference = "B"

[minimise]
{extra}
"#
        )
    };
    for (extra, needle) in [
        (
            "over = \"C.init.nothing\"\nrange = [0.0, 1.0]\nlabel = \"C\"",
            "minimise.range",
        ),
        (
            "over = \"C.init.lambda1\"\nrange = [1.0, 0.0]\nlabel = \"C\"",
            "minimise.range",
        ),
        // Finite ends whose width overflows to infinity.
        (
            "over = \"C.init.lambda1\"\nrange = [-1e308, 1e308]\nlabel = \"C\"",
            "finite width",
        ),
        (
            "over = \"C.init.lambda1\"\nrange = [0.0, 1.0]\nlabel = \"B\"",
            "minimise.label",
        ),
        (
            "over = \"C.init.lambda1\"\nrange = [0.0, 1.0]\nlabel = \"C\"\nsamples = 2",
            "minimise.samples",
        ),
        (
            "over = \"D.init.lambda1\"\nrange = [0.0, 1.0]\nlabel = \"C\"",
            "minimise.over",
        ),
        // A name of every formulation would move the reference B as well.
        (
            "over = \"init.omega_theta\"\nrange = [0.1, 1.0]\nlabel = \"C\"",
            "minimise.over",
        ),
        (
            "over = \"B.init.omega_theta\"\nrange = [0.1, 1.0]\nlabel = \"C\"",
            "minimised formulation alone",
        ),
    ] {
        let file = experiment(&root, "bad", &base(extra));
        let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{extra}: {e}");
        assert!(e.contains(needle), "{extra}: `{needle}` not in {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
    let _ = std::fs::remove_dir_all(&root);
}
