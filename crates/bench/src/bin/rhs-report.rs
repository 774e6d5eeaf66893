//! Prints the cost of one right-hand-side evaluation of every formulation
//! (automatic differentiation) against the hand-written sleigh equations,
//! as a markdown table with the ratio AD / hand-written.
//!
//! `cargo run --release -p nonholo-bench --bin rhs-report [-- --batches N --batch-ms MS]`
//!
//! Criterion (`cargo bench -p nonholo-bench --bench rhs`) times the same
//! evaluations with confidence intervals; this binary gives the table, and
//! writes it to `results/rhs-report/report.md` (run from the repository
//! root), whose ratios docs/performance.md quotes.

use std::process::ExitCode;

use nonholo_bench::setup::{RhsCase, embedding_explicit, reduced_c_case, residual_case, rhs_pairs};
use nonholo_bench::timing::{batch_args, keep, paired_ns};

/// Checks that a case evaluates, with its name in the message.
fn check(case: &mut RhsCase, dy: &mut [f64]) -> Result<(), String> {
    case.eval(dy)
        .map_err(|e| format!("{}: {}", case.name, e.message))
}

use std::fmt::Write as _;

/// Prints a line and keeps it for the report file.
macro_rules! out {
    ($buf:expr) => {{
        println!();
        $buf.push('\n');
    }};
    ($buf:expr, $($arg:tt)*) => {{
        let line = format!($($arg)*);
        println!("{line}");
        let _ = writeln!($buf, "{line}");
    }};
}

fn run() -> Result<(), String> {
    let mut report = String::new();
    let (batches, batch_ms) = batch_args("rhs-report [--batches N] [--batch-ms MS]")?;
    // Every case twice: with native code (the default), and built while
    // it is off, so that its programs run in the interpreter and its KKT
    // systems in the Rust solve.
    let mut pairs: Vec<(RhsCase, RhsCase, &str)> = Vec::new();
    for native in [true, false] {
        nonholo_core::jit::set_enabled(native);
        let suffix = if native { "" } else { ", interpreter" };
        for (ad, hand) in rhs_pairs().map_err(|e| e.to_string())? {
            pairs.push((ad, hand, suffix));
        }
    }
    nonholo_core::jit::set_enabled(true);
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    out!(
        report,
        "One evaluation at the generic sleigh state (a = 0.4, α = 0.3, potential = com); \
         AD and baseline timed in {} alternating batches of ~{} ms each, medians, and the \
         median of the per-batch ratios; load average before: {}. Rows marked `interpreter` \
         were built with native code off (`nonholo_core::jit`): their programs run in the \
         interpreter and their KKT systems in the Rust solve.\n",
        batches,
        batch_ms,
        load.split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    );
    out!(
        report,
        "| right-hand side by AD | dim | AD (ns) | hand-written baseline | dim | hand (ns) | ratio AD/hand |"
    );
    out!(report, "|---|---|---|---|---|---|---|");
    let ms = batch_ms;
    let mut jac_lines = Vec::new();
    for (ad, hand, suffix) in pairs.iter_mut() {
        let (mut dy_ad, mut dy_hand) = (vec![0.0; ad.dim()], vec![0.0; hand.dim()]);
        check(ad, &mut dy_ad)?;
        check(hand, &mut dy_hand)?;
        let (t_ad, t_hand, ratio) = paired_ns(
            || {
                let _ = keep(ad.eval(keep(&mut dy_ad)));
            },
            || {
                let _ = keep(hand.eval(keep(&mut dy_hand)));
            },
            batches,
            ms,
        );
        out!(
            report,
            "| {}{suffix} | {} | {t_ad:.0} | {} | {} | {t_hand:.1} | {ratio:.1} |",
            ad.what,
            ad.dim(),
            hand.what,
            hand.dim(),
        );
        if !matches!(ad.name, "B" | "visc" | "visc adapted") {
            continue;
        }
        let dim = ad.dim();
        let mut jac = vec![0.0; dim * dim];
        if !ad
            .jacobian(&mut jac)
            .map_err(|e| format!("{}: {}", ad.name, e.message))?
        {
            return Err(format!("{}: no Jacobian", ad.name));
        }
        // The Jacobian against one evaluation of the same right-hand side
        // (one system, two closures: a RefCell, whose cost is negligible
        // against microseconds).
        let (t_jac, per_rhs) = {
            let shared = std::cell::RefCell::new(&mut *ad);
            let (t_jac, _, per_rhs) = paired_ns(
                || {
                    let _ = keep(shared.borrow_mut().jacobian(keep(&mut jac)));
                },
                || {
                    let _ = keep(shared.borrow_mut().eval(keep(&mut dy_ad)));
                },
                batches,
                ms,
            );
            (t_jac, per_rhs)
        };
        // And against the analytic Jacobian of the reduced equations (B).
        let versus_hand = if ad.name == "B" {
            let hd = hand.dim();
            let mut hjac = vec![0.0; hd * hd];
            let (_, t_hj, r) = paired_ns(
                || {
                    let _ = keep(ad.jacobian(keep(&mut jac)));
                },
                || {
                    let _ = keep(hand.jacobian(keep(&mut hjac)));
                },
                batches,
                ms,
            );
            format!("analytic, {} | {t_hj:.1} | {r:.1}", hand.what)
        } else {
            "— | — | —".to_string()
        };
        jac_lines.push(format!(
            "| {}{suffix} | {dim} | {t_jac:.0} | {per_rhs:.1} | {versus_hand} |",
            ad.what
        ));
    }
    let mut reduced_c = reduced_c_case().map_err(|e| e.to_string())?;
    let mut dy_c = vec![0.0; reduced_c.dim()];
    check(&mut reduced_c, &mut dy_c)?;
    let mut a = residual_case().map_err(|e| e.to_string())?;
    let mut res = vec![0.0; a.dim()];
    a.eval(&mut res)
        .map_err(|e| format!("A residual: {}", e.message))?;
    // One row against the hand-written reduced C, timed in alternating
    // batches with it.
    let mut against_c = |report: &mut String, what: &str, dim: usize, ad: &mut dyn FnMut()| {
        let (t, t_c, ratio) = paired_ns(
            ad,
            || {
                let _ = keep(reduced_c.eval(keep(&mut dy_c)));
            },
            batches,
            ms,
        );
        out!(
            report,
            "| {what} | {dim} | {t:.0} | {} | {} | {t_c:.1} | {ratio:.1} |",
            reduced_c.what,
            reduced_c.dim(),
        );
    };
    against_c(
        &mut report,
        "A (embedding), residual F(t, y, y′) of (19)",
        a.dim(),
        &mut || {
            let _ = keep(a.eval(keep(&mut res)));
        },
    );
    // A's explicit form three ways: by the traced programs as native code
    // (the default), by the same programs in the interpreter (traced at the
    // first solve, in `check`, while native code is off), and by the dual
    // passes over the jets.
    for (traced, native) in [(true, true), (true, false), (false, true)] {
        nonholo_core::jit::set_enabled(native);
        let mut ae = embedding_explicit(traced).map_err(|e| e.to_string())?;
        let mut dy = vec![0.0; ae.dim()];
        let checked = check(&mut ae, &mut dy);
        nonholo_core::jit::set_enabled(true);
        checked?;
        let suffix = if native { "" } else { ", interpreter" };
        let (what, dim) = (format!("{}{suffix}", ae.what), ae.dim());
        against_c(&mut report, &what, dim, &mut || {
            let _ = keep(ae.eval(keep(&mut dy)));
        });
    }
    out!(report);
    out!(
        report,
        "| Jacobian ∂f/∂y by AD | dim | AD (ns) | AD Jacobian / AD rhs | hand-written baseline | hand (ns) | ratio AD/hand |"
    );
    out!(report, "|---|---|---|---|---|---|---|");
    for line in jac_lines {
        out!(report, "{line}");
    }
    let dir = std::path::Path::new("results/rhs-report");
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let path = dir.join("report.md");
    std::fs::write(&path, report).map_err(|e| format!("{}: {e}", path.display()))?;
    Ok(())
}

fn main() -> ExitCode {
    nonholo_bench::report_main(run)
}
