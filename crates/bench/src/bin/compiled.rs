//! The KKT system of formulations B and C by the scalar dual passes
//! (`Jet`, one evaluation of the Lagrangian per derivative direction)
//! against the compiled program (`nonholo_core::compiled`: the Lagrangian
//! and constraints traced once, differentiated on the graph, common
//! subexpressions shared), run as native code (`nonholo_core::jit`, the
//! default) and in the interpreter, for every scene: assembly and solve of
//! one right-hand side, over `f64` and over `Dual64` (one Jacobian column),
//! timed in alternating batches (passes against native code, interpreter
//! against native code); the program's size, the time to build it and the
//! time Cranelift takes to make its native code.
//!
//! `cargo run --release -p nonholo-bench --bin compiled [-- --batches N --batch-ms MS]`,
//! from the repository root: the table is also written to
//! `results/compiled/kkt.csv`, whose numbers docs/performance.md quotes.

use std::process::ExitCode;
use std::time::Instant;

use nonholo_bench::timing::{batch_args, keep, paired_ns};
use nonholo_core::kkt::{Ideal, Kkt};
use nonholo_core::scene::{Augmented, Lagrangian, Scalar, ScalarField};
use nonholo_core::stab::Stabilisation;
use nonholo_core::{Scene, SceneInfo};
use nonholo_scenes::{SceneVisitor, build};
use num_dual::Dual64;

/// A state of `n` coordinates away from every scene's singular set.
fn state(n: usize, np: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let q = (0..n).map(|i| 0.3 + 0.17 * i as f64).collect();
    let qd = (0..n).map(|i| 0.9 - 0.23 * i as f64).collect();
    let p = (0..np).map(|i| 0.4 - 0.1 * i as f64).collect();
    (q, qd, p)
}

struct Line {
    scene: &'static str,
    formulation: &'static str,
    scalar: &'static str,
    passes_ns: f64,
    compiled_ns: f64,
    ratio: f64,
    interpreted_ns: f64,
    native_ratio: f64,
    ops: usize,
    transcendentals: usize,
    build_us: f64,
    native_us: f64,
}

fn time<T: Scalar, F: ScalarField, S: Scene>(
    scene: &S,
    ell: &F,
    np: usize,
    formulation: &'static str,
    scalar: &'static str,
    lift: impl Fn(f64, bool) -> T,
    (batches, batch_ms): (usize, f64),
) -> Result<Line, String> {
    let info: &SceneInfo = scene.info();
    let (q, qd, p) = state(info.n(), np);
    let q: Vec<T> = q
        .iter()
        .enumerate()
        .map(|(i, &x)| lift(x, i == 0))
        .collect();
    let qd: Vec<T> = qd.iter().map(|&x| lift(x, false)).collect();
    let p: Vec<T> = p.iter().map(|&x| lift(x, false)).collect();
    let t = lift(0.3, false);
    let rows = Ideal(Stabilisation::None);
    let mut passes: Kkt<T> = Kkt::for_scene(info);
    // The program built with native code off: the trace, the derivatives
    // on the graph and the straight-line program.
    nonholo_core::jit::set_enabled(false);
    let start = Instant::now();
    let mut interpreted: Kkt<T> = Kkt::for_scene(info);
    let built = interpreted.compile(ell, np, scene);
    let build_us = start.elapsed().as_secs_f64() * 1e6;
    nonholo_core::jit::set_enabled(true);
    built.map_err(|e| format!("{}: {e}", info.name))?;
    // The same with native code, and Cranelift's time for it (nothing
    // where an earlier line compiled the same shape).
    let before = nonholo_core::jit::compile_stats().2;
    let mut compiled: Kkt<T> = Kkt::for_scene(info);
    compiled
        .compile(ell, np, scene)
        .map_err(|e| format!("{}: {e}", info.name))?;
    let c = compiled.compiled().ok_or("compiled")?;
    c.prepare_native();
    let native_us = (nonholo_core::jit::compile_stats().2 - before) * 1e6;
    let (ops, transcendentals, _) = c.size();
    let solve = |k: &mut Kkt<T>| {
        let r = k.solve(ell, keep(&p), scene, &rows, keep(t), keep(&q), keep(&qd));
        keep(&r);
    };
    solve(&mut passes);
    solve(&mut compiled);
    solve(&mut interpreted);
    if compiled.sol != interpreted.sol {
        return Err(format!(
            "{} {formulation}: native code and the interpreter differ",
            info.name
        ));
    }
    let worst = passes
        .qdd()
        .iter()
        .zip(compiled.qdd())
        .map(|(a, b)| (a.re() - b.re()).abs() / (1.0 + a.re().abs()))
        .fold(0.0f64, f64::max);
    if worst > 1e-12 {
        return Err(format!(
            "{} {formulation}: q̈ differs by {worst:e}",
            info.name
        ));
    }
    let (passes_ns, compiled_ns, ratio) = paired_ns(
        || solve(&mut passes),
        || solve(&mut compiled),
        batches,
        batch_ms,
    );
    let (interpreted_ns, _, native_ratio) = paired_ns(
        || solve(&mut interpreted),
        || solve(&mut compiled),
        batches,
        batch_ms,
    );
    Ok(Line {
        scene: info.name,
        formulation,
        scalar,
        passes_ns,
        compiled_ns,
        ratio,
        interpreted_ns,
        native_ratio,
        ops,
        transcendentals,
        build_us,
        native_us,
    })
}

struct Visit((usize, f64));

impl SceneVisitor for Visit {
    type Output = Result<Vec<Line>, String>;
    fn visit<S: Scene>(self, scene: S) -> Self::Output {
        let s = scene.info().s();
        let b = self.0;
        let re = |x: f64, _: bool| x;
        let du = |x: f64, seed: bool| Dual64::new(x, if seed { 1.0 } else { 0.0 });
        Ok(vec![
            time(&scene, &Lagrangian(&scene), 0, "B", "f64", re, b)?,
            time(&scene, &Augmented(&scene), s, "C", "f64", re, b)?,
            time(&scene, &Lagrangian(&scene), 0, "B", "Dual64", du, b)?,
            time(&scene, &Augmented(&scene), s, "C", "Dual64", du, b)?,
        ])
    }
}

fn run() -> Result<(), String> {
    let b = batch_args("compiled [--batches N] [--batch-ms MS]")?;
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "One KKT assembly and solve (M, Q, G, ġ₀, F, ḟ, f̈₀; block elimination or LU) per \
         line, the passes against the program as native code and the interpreted program \
         against it, timed in {} alternating batches of ~{} ms, medians and the median \
         per-batch ratio; build: the trace and the program; native: Cranelift's time for its \
         code; load average before: {}.\n",
        b.0,
        b.1,
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    println!(
        "| scene | formulation | scalar | passes (ns) | interpreted (ns) | native (ns) | speed-up over passes | over interpreter | instructions | of them sin, cos, ... | build (µs) | native (µs) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut csv = String::from(
        "scene,formulation,scalar,passes_ns,compiled_ns,speedup,instructions,transcendentals,build_us,interpreted_ns,native_speedup,native_us\n",
    );
    for info in nonholo_scenes::ALL {
        let scene = build(info.name, &[]).map_err(|e| e.to_string())?;
        for l in scene.visit(Visit(b))? {
            // One row, written in full to the CSV and rounded in the table.
            let cells = [
                l.scene.to_string(),
                l.formulation.to_string(),
                l.scalar.to_string(),
                format!("{:.1}", l.passes_ns),
                format!("{:.1}", l.compiled_ns),
                format!("{:.3}", l.ratio),
                l.ops.to_string(),
                l.transcendentals.to_string(),
                format!("{:.1}", l.build_us),
                format!("{:.1}", l.interpreted_ns),
                format!("{:.3}", l.native_ratio),
                format!("{:.1}", l.native_us),
            ];
            csv.push_str(&format!("{}\n", cells.join(",")));
            println!(
                "| {} | {} | {} | {:.0} | {:.0} | {:.0} | {:.1} | {:.1} | {} | {} | {:.0} | {:.0} |",
                cells[0],
                cells[1],
                cells[2],
                l.passes_ns,
                l.interpreted_ns,
                l.compiled_ns,
                l.ratio,
                l.native_ratio,
                cells[6],
                cells[7],
                l.build_us,
                l.native_us
            );
        }
    }
    let dir = std::path::Path::new("results/compiled");
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let path = dir.join("kkt.csv");
    std::fs::write(&path, csv).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(())
}

fn main() -> ExitCode {
    nonholo_bench::report_main(run)
}
