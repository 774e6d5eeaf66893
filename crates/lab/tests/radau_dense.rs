//! `--radau-dense` / `radau_dense`: Radau IIA's continuous extension as the
//! command line and the run record see it.

use std::process::Command;

/// Runs `nonholo simulate ARGS`; returns (exit code, stdout + stderr).
fn simulate(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_nonholo"))
        .arg("simulate")
        .args(args)
        .output()
        .expect("nonholo runs");
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (out.status.code().unwrap_or(-1), text)
}

const VISC: [&str; 12] = [
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
];

/// The record names the extension only when it is not the default; both
/// runs take the same steps (the extension changes no step).
#[test]
fn the_record_names_the_extension_and_the_steps_are_the_same() {
    let dir = std::env::temp_dir().join(format!("nonholo-radau-dense-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut runs = Vec::new();
    for dense in ["collocation", "hermite"] {
        let out = dir.join(format!("{dense}.json"));
        let mut args = VISC.to_vec();
        args.extend(["--radau-dense", dense, "--out", out.to_str().unwrap()]);
        let (code, text) = simulate(&args);
        assert_eq!(code, 0, "{text}");
        let run: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        runs.push(run);
    }
    assert!(
        runs[0]["integrator"]["radau5"]
            .get("dense_output")
            .is_none()
    );
    assert_eq!(runs[1]["integrator"]["radau5"]["dense_output"], "hermite");
    assert_eq!(runs[0]["stats"]["steps"], runs[1]["stats"]["steps"]);
    assert_eq!(runs[0]["stats"]["rhs_evals"], runs[1]["stats"]["rhs_evals"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// An unknown name is refused naming the flag; A's implicit form (a DAE
/// under radau5) refuses the Hermite extension with the reason.
#[test]
fn bad_names_and_implicit_forms_are_refused() {
    let mut args = VISC.to_vec();
    args.extend(["--radau-dense", "cubic"]);
    let (code, text) = simulate(&args);
    assert_ne!(code, 0);
    assert!(
        text.contains("--radau-dense") && text.contains("collocation, hermite"),
        "{text}"
    );
    let (code, text) = simulate(&[
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
    assert_ne!(code, 0, "{text}");
    assert!(text.contains("dense_output = hermite"), "{text}");
}
