//! How the cost of formulation B grows with the size of the scene: the
//! train of `N` hitched sleighs (`sleigh-train`, `3N` coordinates, `N`
//! blades, `2(N − 1)` hitches) for `N` from 1 to 1000 (issue 13, parts 2–3).
//!
//! `cargo run --release -p nonholo-bench --bin scale-report [-- --rounds R --out DIR]`
//!
//! Per `N`, at the train's default state (in line, lead sleigh at
//! `u = 1 m/s`, `ω = 0.3 rad/s`):
//!
//! * the one-off compilation of `L`, `g`, `f` into one program (seconds),
//!   its instructions and the structural nonzeros of the KKT matrix;
//! * one right-hand side of B as the integrators call it (the sparse KKT
//!   solve of [`nonholo_core::sparse`] above its threshold);
//! * the KKT solve (the program's evaluation included), sparse and dense,
//!   at every size (dense up to `N = 100`): where they cross is where
//!   `SPARSE_FROM` belongs;
//! * one Jacobian of the right-hand side (`2·3N` `Dual64` passes, each one
//!   program evaluation and one sparse solve with its derivative part; up
//!   to `N = 300`: the Jacobian of the chain is dense, `(6N)²` entries);
//! * one DOP853 run of B over `[0, 2] s` at `rtol = atol = 1e-8` (the
//!   model built, its program compiled, beforehand): steps, right-hand
//!   sides, wall time, and the part of it that is not right-hand sides
//!   (the check of the initial data, the monitors of every step, the
//!   integrator's own arithmetic);
//! * one Radau IIA run of B, same span and tolerances, up to `N = 100`:
//!   steps, Jacobians, LU factorisations, wall time per step (its Newton
//!   matrices are dense: the Jacobian of the chain's right-hand side is);
//! * B as an index-1 DAE in `(q, q̇, q̈, μ)` ([`nonholo_chetaev::dae`]) at
//!   every size: its colours (the `Dual64` passes of one Jacobian), one
//!   residual, one sparse Jacobian, and one Radau IIA run with sparse
//!   iteration matrices (faer, real and complex) over the same span and
//!   tolerances, called directly (`solve_implicit`: no initial-data check,
//!   no monitors), with the largest difference of its final `(q, q̇)` from
//!   the DOP853 run's.
//!
//! Native code ([`nonholo_core::jit`]) is switched off for the whole
//! report: it is made only for programs of up to
//! [`nonholo_core::jit::MAX_INSTRUCTIONS`] instructions (`N` up to about
//! 270), and one regime from `N = 1` to 1000 keeps the fitted exponents
//! about the growth with `N`, not about where native code stops.
//!
//! The timings of one call are interleaved across the sizes, `R` rounds
//! (default 3), medians reported; the compilation and the two runs are
//! measured once per size.
//! The exponent is the least-squares slope of log cost against log `N` over
//! `N ≥ 10`. `scale.csv` and `fits.csv` in DIR (default `results/scale`)
//! keep the numbers docs/performance.md quotes; `scale.png` and `scale.svg`
//! plot them.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

use nonholo_chetaev::Chetaev;
use nonholo_core::compiled::Compiled;
use nonholo_core::dae::KktDae;
use nonholo_core::integrate::{ImplicitSystem, Method, OdeSystem, Options, solve_implicit};
use nonholo_core::kkt::{Ideal, Kkt};
use nonholo_core::scene::Lagrangian;
use nonholo_core::sparse::SparseKkt;
use nonholo_core::stab::Stabilisation;
use nonholo_core::{Params, RunConfig, Scene, simulate};
use nonholo_lab::plot::{LinePlot, Series, line_plot};
use nonholo_scenes::Train;

const SIZES: [usize; 11] = [1, 2, 3, 4, 5, 7, 10, 30, 100, 300, 1000];
/// Largest `N` whose KKT system is also solved dense.
const DENSE_UP_TO: usize = 100;
/// Largest `N` whose Jacobian is timed (it is dense: `(6N)²` entries).
const JACOBIAN_UP_TO: usize = 300;
/// Largest `N` run with Radau IIA (dense `6N × 6N` Newton matrices).
const RADAU_UP_TO: usize = 100;

/// Seconds per call of `f`, over calls adding up to about `ms`.
fn per_call(mut f: impl FnMut(), ms: f64) -> f64 {
    let start = Instant::now();
    f();
    let first = start.elapsed().as_secs_f64();
    let calls = ((ms * 1e-3 / first.max(1e-9)).ceil() as usize).clamp(1, 1_000_000);
    let start = Instant::now();
    for _ in 0..calls {
        f();
    }
    start.elapsed().as_secs_f64() / calls as f64
}

fn median(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    s[s.len() / 2]
}

/// Least-squares slope of `ln y` against `ln x` over finite pairs with `x ≥ 10`.
fn slope(x: &[usize], y: &[f64]) -> f64 {
    let (lx, ly): (Vec<f64>, Vec<f64>) = x
        .iter()
        .zip(y)
        .filter(|(a, b)| **a >= 10 && b.is_finite() && **b > 0.0)
        .map(|(a, b)| ((*a as f64).ln(), b.ln()))
        .unzip();
    let n = lx.len() as f64;
    if n < 2.0 {
        return f64::NAN;
    }
    let (mx, my) = (lx.iter().sum::<f64>() / n, ly.iter().sum::<f64>() / n);
    let sxy: f64 = lx.iter().zip(&ly).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = lx.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

/// One size: the scene, B bound to it, the state, and the measurements.
struct Size {
    n_sleighs: usize,
    train: Train,
    b: Chetaev<Train>,
    y: Vec<f64>,
    program: Arc<Compiled>,
    nonzeros: usize,
    compile_s: Vec<f64>,
    rhs_s: Vec<f64>,
    sparse_s: Vec<f64>,
    dense_s: Vec<f64>,
    jacobian_s: Vec<f64>,
    run: Option<(usize, usize, f64)>,
    /// `(q, q̇)` at the end of the DOP853 run.
    run_end: Vec<f64>,
    /// Radau IIA: steps, Jacobians, LU factorisations, wall time.
    radau: Option<(usize, usize, usize, f64)>,
    /// B as an index-1 DAE, its consistent `(y, y')` at the state.
    dae: KktDae<Train>,
    dae_y: Vec<f64>,
    dae_yp: Vec<f64>,
    dae_residual_s: Vec<f64>,
    dae_jacobian_s: Vec<f64>,
    /// Radau IIA on the DAE: steps, Jacobians, LU factorisations, wall
    /// time, largest difference of `(q, q̇)` from the DOP853 run at the end.
    dae_radau: Option<(usize, usize, usize, f64, f64)>,
}

impl Size {
    fn new(n_sleighs: usize) -> Result<Size, String> {
        let info = nonholo_scenes::trailer::INFO;
        let p = Params::resolve(
            info.params,
            &[("N".to_string(), n_sleighs.to_string())],
            "parameter",
        )
        .map_err(|e| e.to_string())?;
        let train = Train::from_params(&p).map_err(|e| e.to_string())?;
        let q = train.default_q();
        let mut qd = vec![0.0; q.len()];
        train.velocities_from(&q, &[1.0, 0.3], &mut qd);
        let y = [q, qd].concat();
        let b = Chetaev::new(train.clone(), Params::defaults(nonholo_chetaev::OPTIONS))
            .map_err(|e| e.to_string())?;
        let start = Instant::now();
        let program =
            Arc::new(Compiled::new(&Lagrangian(&train), 0, &train).map_err(|e| e.to_string())?);
        let compile = start.elapsed().as_secs_f64();
        let ti = train.info();
        let nonzeros = SparseKkt::new(program.kkt_entries(), ti.n(), ti.n() + ti.s() + ti.k())
            .map(|s| s.nonzeros())
            .unwrap_or(0);
        let dae = nonholo_chetaev::dae(train.clone(), Params::defaults(nonholo_chetaev::OPTIONS))
            .map_err(|e| e.to_string())?;
        let (dae_y, dae_yp) = dae
            .initial(0.0, &y[..ti.n()], &y[ti.n()..], &[])
            .map_err(|e| e.to_string())?;
        Ok(Size {
            n_sleighs,
            train,
            b,
            y,
            program,
            nonzeros,
            compile_s: vec![compile],
            rhs_s: Vec::new(),
            sparse_s: Vec::new(),
            dense_s: Vec::new(),
            jacobian_s: Vec::new(),
            run: None,
            run_end: Vec::new(),
            radau: None,
            dae,
            dae_y,
            dae_yp,
            dae_residual_s: Vec::new(),
            dae_jacobian_s: Vec::new(),
            dae_radau: None,
        })
    }

    fn measure(&mut self, ms: f64) -> Result<(), String> {
        let dim = self.y.len();
        let mut dy = vec![0.0; dim];
        self.b
            .rhs(0.0, &self.y, &mut dy)
            .map_err(|e| format!("N = {}: {}", self.n_sleighs, e.message))?;
        let (b, y) = (&mut self.b, &self.y);
        self.rhs_s.push(per_call(
            || {
                let _ = std::hint::black_box(b.rhs(0.0, y, &mut dy));
            },
            ms,
        ));
        let info = self.train.info();
        let n = info.n();
        let (q, qd) = self.y.split_at(n);
        let rows = Ideal(Stabilisation::None);
        let train = &self.train;
        let mut kkt: Kkt<f64> = Kkt::for_scene(info);
        kkt.use_program(self.program.clone());
        let solve = |kkt: &mut Kkt<f64>| {
            kkt.solve(&Lagrangian(train), &[], train, &rows, 0.0, q, qd)
                .map_err(|e| format!("N = {}: {e}", self.n_sleighs))
        };
        kkt.force_sparse()
            .map_err(|e| format!("N = {}: {e}", self.n_sleighs))?;
        solve(&mut kkt)?;
        self.sparse_s.push(per_call(
            || {
                let _ = std::hint::black_box(solve(&mut kkt));
            },
            ms,
        ));
        if self.n_sleighs <= DENSE_UP_TO {
            kkt.force_dense();
            solve(&mut kkt)?;
            self.dense_s.push(per_call(
                || {
                    let _ = std::hint::black_box(solve(&mut kkt));
                },
                ms,
            ));
        }
        if self.n_sleighs <= JACOBIAN_UP_TO {
            let mut jac = vec![0.0; dim * dim];
            let (b, y) = (&mut self.b, &self.y);
            self.jacobian_s.push(per_call(
                || {
                    let _ = std::hint::black_box(b.jacobian(0.0, y, &mut jac));
                },
                ms,
            ));
        }
        let dim = self.dae.dim();
        let sp = self.dae.sparsity().expect("the DAE form is sparse");
        let (mut jy, mut jyp) = (vec![0.0; sp.jy.len()], vec![0.0; sp.jyp.len()]);
        let mut res = vec![0.0; dim];
        let (dae, y, yp) = (&mut self.dae, &self.dae_y, &self.dae_yp);
        self.dae_residual_s.push(per_call(
            || {
                let _ = std::hint::black_box(dae.residual(0.0, y, yp, &mut res));
            },
            ms,
        ));
        self.dae_jacobian_s.push(per_call(
            || {
                let _ = std::hint::black_box(dae.jacobians(0.0, y, yp, &mut jy, &mut jyp));
            },
            ms,
        ));
        if self.run.is_none() {
            let (steps, rhs, _, _, wall) = self.simulate(Method::Dop853)?;
            self.run = Some((steps, rhs, wall));
            self.dae_radau = Some(self.simulate_dae()?);
            if self.n_sleighs <= RADAU_UP_TO {
                let (steps, _, jac, lu, wall) = self.simulate(Method::Radau5)?;
                self.radau = Some((steps, jac, lu, wall));
            }
        }
        Ok(())
    }
}

impl Size {
    /// Radau IIA on B's DAE form over `[0, 2] s` at `rtol = atol = 1e-8`:
    /// steps, Jacobians, LU factorisations, wall time, and the largest
    /// difference of its final `(q, q̇)` from the DOP853 run's.
    fn simulate_dae(&mut self) -> Result<(usize, usize, usize, f64, f64), String> {
        let opts = Options {
            rtol: 1e-8,
            atol: 1e-8,
            output: vec![0.0, 2.0],
            ..Options::default()
        };
        let start = Instant::now();
        let r = solve_implicit(&mut self.dae, 0.0, &self.dae_y, &self.dae_yp, 2.0, &opts);
        let wall = start.elapsed().as_secs_f64();
        let r = r.map_err(|e| format!("N = {}, DAE Radau IIA: {e}", self.n_sleighs))?;
        let diff = self
            .run_end
            .iter()
            .zip(&r.y_last)
            .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
        let st = &r.stats;
        Ok((
            st.steps,
            st.jacobian_evals,
            st.lu_decompositions,
            wall,
            diff,
        ))
    }

    /// One run of B over `[0, 2] s` at `rtol = atol = 1e-8`, the model
    /// built (its program compiled) before the clock starts: steps,
    /// right-hand sides, Jacobians, LU factorisations, wall time.
    fn simulate(&mut self, method: Method) -> Result<(usize, usize, usize, usize, f64), String> {
        let model = Chetaev::new(
            self.train.clone(),
            Params::defaults(nonholo_chetaev::OPTIONS),
        )
        .map_err(|e| e.to_string())?;
        let n = self.train.info().n();
        let initial = nonholo_core::Initial {
            t0: 0.0,
            q: self.y[..n].to_vec(),
            qd: self.y[n..].to_vec(),
            extra: Vec::new(),
        };
        let start = Instant::now();
        let r = simulate(
            Box::new(model),
            initial,
            RunConfig {
                method,
                options: Options {
                    rtol: 1e-8,
                    atol: 1e-8,
                    output: vec![0.0, 2.0],
                    ..Options::default()
                },
                t_end: 2.0,
                project_init: false,
            },
        );
        let wall = start.elapsed().as_secs_f64();
        let fail = |e: String| format!("N = {}, {method:?}: the run failed: {e}", self.n_sleighs);
        let r = r.map_err(|e| fail(e.to_string()))?;
        if let Some(f) = &r.failure {
            return Err(fail(f.to_string()));
        }
        if method == Method::Dop853 {
            self.run_end = r.solution.y_last.clone();
        }
        let st = &r.solution.stats;
        Ok((
            st.steps,
            st.rhs_evals,
            st.jacobian_evals,
            st.lu_decompositions,
            wall,
        ))
    }
}

fn run() -> Result<(), String> {
    // One regime for every size: see the module docs.
    nonholo_core::jit::set_enabled(false);
    let mut rounds = 3usize;
    let mut out = PathBuf::from("results/scale");
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--rounds" => {
                let v = it.next().ok_or("--rounds needs a value")?;
                rounds = v
                    .parse()
                    .map_err(|_| format!("--rounds: cannot read `{v}` as a count"))?;
            }
            "--out" => out = PathBuf::from(it.next().ok_or("--out needs a directory")?),
            "-h" | "--help" => {
                println!("usage: scale-report [--rounds R] [--out DIR]");
                return Ok(());
            }
            other => return Err(format!("unknown argument `{other}` (try --help)")),
        }
    }
    let mut sizes = Vec::new();
    for &n in &SIZES {
        eprintln!("scale-report: compiling N = {n}");
        sizes.push(Size::new(n)?);
    }
    for round in 0..rounds {
        eprintln!("scale-report: round {}/{rounds}", round + 1);
        for s in &mut sizes {
            s.measure(40.0)?;
        }
    }
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let path = out.join("scale.csv");
    let mut w = csv::Writer::from_path(&path).map_err(|e| format!("{}: {e}", path.display()))?;
    w.write_record([
        "N",
        "n",
        "kkt_size",
        "kkt_nonzeros",
        "instructions",
        "compile_s",
        "rhs_us",
        "kkt_sparse_us",
        "kkt_dense_us",
        "jacobian_ms",
        "run_steps",
        "run_rhs",
        "run_s",
        "run_other_s",
        "radau_steps",
        "radau_jacobians",
        "radau_lu",
        "radau_s",
        "radau_ms_per_step",
        "dae_colours",
        "dae_residual_us",
        "dae_jacobian_ms",
        "dae_radau_steps",
        "dae_radau_jacobians",
        "dae_radau_lu",
        "dae_radau_s",
        "dae_radau_ms_per_step",
        "dae_vs_dop853",
    ])
    .map_err(|e| e.to_string())?;
    println!(
        "| N | n | KKT size | nonzeros | instructions | compile (s) | RHS (µs) | KKT sparse (µs) | KKT dense (µs) | Jacobian (ms) | DOP853: steps, RHS, s | DOP853, not RHS (s) | Radau: steps, Jacobians, LU | Radau (ms/step) | DAE: colours, residual (µs), Jacobian (ms) | DAE Radau: steps, Jacobians, LU, ms/step | DAE − DOP853 |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let cols: Vec<[f64; 5]> = sizes
        .iter()
        .map(|s| {
            [
                median(&s.compile_s),
                median(&s.rhs_s) * 1e6,
                median(&s.sparse_s) * 1e6,
                median(&s.dense_s) * 1e6,
                median(&s.jacobian_s) * 1e3,
            ]
        })
        .collect();
    for (s, c) in sizes.iter().zip(&cols) {
        let info = s.train.info();
        let (steps, rhs, wall) = s.run.unwrap_or((0, 0, f64::NAN));
        let other = wall - rhs as f64 * c[1] * 1e-6;
        let (rs, rj, rl, rw) = s.radau.unwrap_or((0, 0, 0, f64::NAN));
        let per_step = rw / rs.max(1) as f64 * 1e3;
        let (ds, dj, dl, dw, dd) = s.dae_radau.unwrap_or((0, 0, 0, f64::NAN, f64::NAN));
        let dae_step = dw / ds.max(1) as f64 * 1e3;
        let (dae_res, dae_jac) = (
            median(&s.dae_residual_s) * 1e6,
            median(&s.dae_jacobian_s) * 1e3,
        );
        let fmt = |v: f64| {
            if v.is_finite() {
                format!("{v:.4}")
            } else {
                String::new()
            }
        };
        w.write_record([
            s.n_sleighs.to_string(),
            info.n().to_string(),
            (info.n() + info.s() + info.k()).to_string(),
            s.nonzeros.to_string(),
            s.program.size().0.to_string(),
            fmt(c[0]),
            fmt(c[1]),
            fmt(c[2]),
            fmt(c[3]),
            fmt(c[4]),
            steps.to_string(),
            rhs.to_string(),
            fmt(wall),
            fmt(other),
            rs.to_string(),
            rj.to_string(),
            rl.to_string(),
            fmt(rw),
            fmt(per_step),
            s.dae.colours().to_string(),
            fmt(dae_res),
            fmt(dae_jac),
            ds.to_string(),
            dj.to_string(),
            dl.to_string(),
            fmt(dw),
            fmt(dae_step),
            format!("{dd:.3e}"),
        ])
        .map_err(|e| e.to_string())?;
        println!(
            "| {} | {} | {} | {} | {} | {:.3} | {:.2} | {} | {} | {} | {steps}, {rhs}, {wall:.3} | {other:.3} | {rs}, {rj}, {rl} | {} | {}, {}, {} | {ds}, {dj}, {dl}, {} | {dd:.1e} |",
            s.n_sleighs,
            info.n(),
            info.n() + info.s() + info.k(),
            s.nonzeros,
            s.program.size().0,
            c[0],
            c[1],
            fmt(c[2]),
            fmt(c[3]),
            fmt(c[4]),
            fmt(per_step),
            s.dae.colours(),
            fmt(dae_res),
            fmt(dae_jac),
            fmt(dae_step),
        );
    }
    w.flush().map_err(|e| e.to_string())?;
    let ns: Vec<usize> = sizes.iter().map(|s| s.n_sleighs).collect();
    let col = |i: usize| -> Vec<f64> {
        // The DAE form, in seconds: residual, Jacobian, Radau step.
        match i {
            6 => return sizes.iter().map(|s| median(&s.dae_residual_s)).collect(),
            7 => return sizes.iter().map(|s| median(&s.dae_jacobian_s)).collect(),
            8 => {
                return sizes
                    .iter()
                    .map(|s| {
                        s.dae_radau
                            .map_or(f64::NAN, |(st, _, _, w, _)| w / st.max(1) as f64)
                    })
                    .collect();
            }
            _ => {}
        }
        if i == 5 {
            // Radau's wall time per step.
            return sizes
                .iter()
                .map(|s| {
                    s.radau
                        .map_or(f64::NAN, |(st, _, _, w)| w / st.max(1) as f64)
                })
                .collect();
        }
        cols.iter().map(|c| c[i]).collect()
    };
    let fits = [
        ("compile", slope(&ns, &col(0))),
        ("rhs", slope(&ns, &col(1))),
        ("kkt_sparse", slope(&ns, &col(2))),
        ("kkt_dense", slope(&ns, &col(3))),
        ("jacobian", slope(&ns, &col(4))),
        ("radau_step", slope(&ns, &col(5))),
        ("dae_residual", slope(&ns, &col(6))),
        ("dae_jacobian", slope(&ns, &col(7))),
        ("dae_radau_step", slope(&ns, &col(8))),
    ];
    println!();
    println!(
        "exponents over N ≥ 10: {}",
        fits.iter()
            .map(|(k, v)| format!("{k} {v:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let fits_path = out.join("fits.csv");
    let mut w =
        csv::Writer::from_path(&fits_path).map_err(|e| format!("{}: {e}", fits_path.display()))?;
    w.write_record(["quantity", "exponent"])
        .map_err(|e| e.to_string())?;
    for (k, v) in fits {
        w.write_record([k.to_string(), format!("{v:.4}")])
            .map_err(|e| e.to_string())?;
    }
    w.flush().map_err(|e| e.to_string())?;
    let xs: Vec<f64> = ns.iter().map(|&n| n as f64).collect();
    // Only the sizes measured (the dense solve stops at N = 100, the
    // Jacobian at 300); the slope is fitted over N ≥ 10.
    let series = |label: &str, i: usize, factor: f64| {
        let (x, y): (Vec<f64>, Vec<f64>) = xs
            .iter()
            .zip(col(i))
            .filter(|(_, v)| v.is_finite())
            .map(|(x, v)| (*x, v * factor))
            .unzip();
        let fit: Vec<usize> = x.iter().map(|v| *v as usize).collect();
        Series {
            label: format!("{label}: slope {:.2} over N ≥ 10", slope(&fit, &y)),
            x,
            y,
            pen: None,
        }
    };
    let plot = LinePlot {
        title: "Cost against size: B on N hitched sleighs (sleigh-train)".into(),
        x_label: "N, sleighs [-]".into(),
        y_label: "wall time per call [s]".into(),
        log_x: true,
        log_y: true,
        series: vec![
            series(
                "B right-hand side (dense KKT below 20 rows, sparse from 20)",
                1,
                1e-6,
            ),
            series("KKT solve, dense LU at every size", 3, 1e-6),
            series(
                "ODE form: Jacobian of the right-hand side (dense, 6N columns)",
                4,
                1e-3,
            ),
            series(
                "ODE form: one Radau IIA step (dense Newton matrices)",
                5,
                1.0,
            ),
            series("DAE form: sparse Jacobian (coloured passes)", 7, 1.0),
            series("DAE form: one Radau IIA step (sparse, faer)", 8, 1.0),
            series("compiling L, g, f (once per scene)", 0, 1.0),
        ],
        ..LinePlot::default()
    };
    let written = line_plot(&plot, &out.join("scale"))?;
    eprintln!("scale-report: wrote {}", path.display());
    for w in written {
        eprintln!("scale-report: wrote {}", w.display());
    }
    Ok(())
}

fn main() -> ExitCode {
    nonholo_bench::report_main(run)
}
