//! Native code ([`nonholo_core::jit`]: the compiled programs over `f64` and
//! `Dual64`, and the small KKT systems with their block elimination)
//! computes what the interpreter and the Rust solve compute, bit for bit,
//! in every formulation on every scene: right-hand sides and Jacobians at
//! states spread over each model's state space. So switching native code on
//! moves no result.
//!
//! One test in its own binary: it switches native code off for the whole
//! process half-way.

use nonholo_core::jit;
use nonholo_lab::formulations::{self, build_model};
use nonholo_scenes::build;

/// Deterministic states in `[−1.5, 1.5]^dim`.
fn states(dim: usize, count: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut x = seed;
    let mut next = || {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((x >> 11) as f64 / (1u64 << 53) as f64) * 3.0 - 1.5
    };
    (0..count)
        .map(|_| (0..dim).map(|_| next()).collect())
        .collect()
}

/// Every right-hand side and Jacobian of every model, as text of their
/// bits (NaN as `NaN`) or of their error, with what they were computed for.
fn evaluate_all() -> Vec<(String, String)> {
    let scenes: Vec<(&str, Vec<(String, String)>)> = nonholo_scenes::ALL
        .iter()
        .map(|info| (info.name, Vec::new()))
        .chain([
            ("sleigh-train", vec![("N".to_string(), "2".to_string())]),
            ("sleigh-train", vec![("N".to_string(), "20".to_string())]),
        ])
        .collect();
    let options: Vec<(&str, Vec<(String, String)>)> = formulations::ALL
        .iter()
        .map(|f| (f.name, Vec::new()))
        .chain([(
            "chetaev",
            vec![("stab".to_string(), "baumgarte".to_string())],
        )])
        .collect();
    let bits = |v: &[f64]| -> String {
        v.iter()
            .map(|x| {
                if x.is_nan() {
                    "NaN".to_string()
                } else {
                    format!("{:016x}", x.to_bits())
                }
            })
            .collect::<Vec<_>>()
            .join(" ")
    };
    let mut all = Vec::new();
    for (scene_name, params) in &scenes {
        for (formulation, opts) in &options {
            let scene = build(scene_name, params).unwrap();
            let Ok(mut model) = build_model(scene, formulation, opts) else {
                continue;
            };
            let Some(sys) = model.ode() else {
                continue;
            };
            let dim = sys.dim();
            for (k, y) in states(dim, 6, 0x5eed + dim as u64).iter().enumerate() {
                let what = format!("{scene_name} {params:?} {formulation} {opts:?} state {k}");
                let t = 0.1 * k as f64;
                let mut dy = vec![0.0; dim];
                let rhs = match sys.rhs(t, y, &mut dy) {
                    Ok(()) => bits(&dy),
                    Err(e) => format!("error: {}", e.message),
                };
                all.push((format!("{what}: rhs"), rhs));
                if k < 2 && dim <= 200 {
                    let mut jac = vec![0.0; dim * dim];
                    let j = match sys.jacobian(t, y, &mut jac) {
                        Ok(true) => bits(&jac),
                        Ok(false) => "none".to_string(),
                        Err(e) => format!("error: {}", e.message),
                    };
                    all.push((format!("{what}: jacobian"), j));
                }
            }
        }
    }
    all
}

#[test]
fn native_code_computes_what_the_interpreter_computes() {
    assert!(jit::enabled(), "native code is on by default");
    let native = evaluate_all();
    jit::set_enabled(false);
    let interpreted = evaluate_all();
    assert_eq!(native.len(), interpreted.len());
    let evaluated = native
        .iter()
        .filter(|(_, v)| !v.starts_with("error"))
        .count();
    // Most states evaluate (the others fail the same way in both).
    assert!(
        evaluated * 2 > native.len(),
        "{evaluated} of {} evaluated",
        native.len()
    );
    for ((what, a), (_, b)) in native.iter().zip(&interpreted) {
        assert_eq!(a, b, "{what}: native code and the interpreter differ");
    }
}
