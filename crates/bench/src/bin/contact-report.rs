//! Prints what the conic programs of `nonholo-contact` cost, as markdown
//! tables: one right-hand side of `gauss` (a Clarabel solve) against B's
//! (an LU of the same KKT system), one friction-cone solve (1 and 2 slip
//! components), and whole friction runs against B on the same motion.
//!
//! `cargo run --release -p nonholo-bench --bin contact-report [-- --batches N --batch-ms MS]`

use std::process::ExitCode;

use nonholo_bench::setup::{OMEGA, Q, U, cartesian, generic_sleigh, options, sleigh};
use nonholo_bench::timing::{batch_args, keep, paired_ns};
use nonholo_chetaev::Chetaev;
use nonholo_contact::conic::FrictionCone;
use nonholo_contact::friction::{self, Friction};
use nonholo_contact::gauss::{self, Gauss};
use nonholo_core::integrate::{Method, OdeSystem, Options};
use nonholo_core::{Error, Initial, Model, Params, RunConfig, init, simulate};
use nonholo_scenes::Sleigh;

/// The default sleigh (the paper's potential) from the figures' data.
fn figure_sleigh() -> Result<(Sleigh, Initial), Error> {
    let s = sleigh(0.4, 0.3, "paper")?;
    let given: Vec<(String, String)> = [("phi", "0.2"), ("u", "2"), ("omega", "0.7")]
        .iter()
        .map(|(a, b)| (a.to_string(), b.to_string()))
        .collect();
    let init = init::resolve(&s, &given, &[])?;
    Ok((s, init))
}

/// One DOP853 run at 1e-12 over [0, 5] s, as the figures make them.
fn one_run(model: Box<dyn Model>, init: Initial) -> (usize, bool) {
    let run = simulate(
        model,
        init,
        RunConfig {
            method: Method::Dop853,
            options: Options {
                rtol: 1e-12,
                atol: 1e-12,
                output: (0..=500).map(|i| i as f64 * 0.01).collect(),
                ..Options::default()
            },
            t_end: 5.0,
            project_init: false,
        },
    )
    .expect("the figures' data are consistent");
    (run.solution.stats.rhs_evals, run.completed())
}

fn run() -> Result<(), String> {
    let (batches, ms) = batch_args("contact-report [--batches N] [--batch-ms MS]")?;
    let e = |e: Error| e.to_string();
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    println!(
        "Timed in {batches} alternating batches of ~{ms} ms, medians and the median of the \
         per-batch ratios; load average before: {}.\n",
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );

    // One right-hand side: gauss (Clarabel) against B (LU), same state.
    let s = generic_sleigh().map_err(e)?;
    let y = cartesian(Q, U, 0.0, OMEGA);
    let mut b = Chetaev::new(s.clone(), Params::defaults(nonholo_chetaev::OPTIONS)).map_err(e)?;
    let mut g = Gauss::new(s, Params::defaults(gauss::OPTIONS)).map_err(e)?;
    let (mut dy_b, mut dy_g) = ([0.0; 6], [0.0; 6]);
    b.rhs(0.0, &y, &mut dy_b).map_err(|e| e.message)?;
    g.rhs(0.0, &y, &mut dy_g).map_err(|e| e.message)?;
    let (t_g, t_b, ratio) = paired_ns(
        || {
            let _ = keep(g.rhs(0.0, &y, keep(&mut dy_g)));
        },
        || {
            let _ = keep(b.rhs(0.0, &y, keep(&mut dy_b)));
        },
        batches,
        ms,
    );
    println!("| one right-hand side (generic sleigh state) | ns | against B's LU |");
    println!("|---|---|---|");
    println!(
        "| gauss: quadratic program, Clarabel (data updated in place) | {t_g:.0} | {ratio:.1}× |"
    );
    println!("| B: KKT system, LU | {t_b:.0} | 1 |");

    // One friction-cone solve, 1 and 2 slip components.
    let mut c1 = FrictionCone::new(1);
    let mut c2 = FrictionCone::new(2);
    let (w1, q1) = ([1.6], [2.0]);
    let (w2, q2) = ([1.5, 0.2, 0.2, 2.0], [1.0, 0.4]);
    let (t1, t2, _) = paired_ns(
        || {
            let _ = keep(c1.solve(&w1, &q1, keep(1.0)));
        },
        || {
            let _ = keep(c2.solve(&w2, &q2, keep(1.0)));
        },
        batches,
        ms,
    );
    println!("\n| one friction-cone solve (second-order cone program, Clarabel) | ns |");
    println!("|---|---|");
    println!("| blade, 1 slip component (sliding: force on the cone) | {t1:.0} |");
    println!("| contact point, 2 slip components (sliding) | {t2:.0} |");

    // Whole runs: friction against B on the figures' motion.
    println!(
        "\n| DOP853 at 1e-12 over [0, 5] s, default sleigh (friction-sleigh's data) | \
         evaluations | run (µs) | B's run (µs) | ratio |"
    );
    println!("|---|---|---|---|---|");
    let (s, init) = figure_sleigh().map_err(e)?;
    for mu in ["0.3", "0.25"] {
        let opts = options(friction::OPTIONS, &[("mu", mu)]).map_err(e)?;
        let make_f = || -> Box<dyn Model> {
            Box::new(Friction::new(s.clone(), opts.clone()).expect("valid options"))
        };
        let make_b = || -> Box<dyn Model> {
            Box::new(
                Chetaev::new(s.clone(), Params::defaults(nonholo_chetaev::OPTIONS))
                    .expect("valid options"),
            )
        };
        let (evals, done) = one_run(make_f(), init.clone());
        if !done {
            return Err(format!("friction μ = {mu}: the run did not complete"));
        }
        let (t_f, t_b, ratio) = paired_ns(
            || {
                let _ = keep(one_run(make_f(), init.clone()));
            },
            || {
                let _ = keep(one_run(make_b(), init.clone()));
            },
            batches.min(11),
            ms.max(50.0),
        );
        let what = if mu == "0.3" {
            "friction, μ = 0.3 (sticks throughout: B's motion)"
        } else {
            "friction, μ = 0.25 (stick, slip at 0.297 s, stick at 2.261 s)"
        };
        println!(
            "| {what} | {evals} | {:.0} | {:.0} | {ratio:.2} |",
            t_f / 1e3,
            t_b / 1e3
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    nonholo_bench::report_main(run)
}
