//! The derivative array `D = [E; Ė; Ë]` of (19) and the columns of its
//! Jacobian that A's explicit form needs ([`crate::ode`]), traced once into
//! straight-line programs ([`nonholo_core::graph`]) and run as native code
//! over `f64`, in the interpreter over complex numbers (the continuation's
//! paths in complex time).
//!
//! [`elo_array`] is evaluated once over [`Tracer`] numbers on the order-4
//! time jet: every operation of the scene's Lagrangian and embedding map on
//! the nested dual numbers is recorded into one graph, in which common
//! subexpressions (the jets' repeated products, the trigonometry at the same
//! angles) exist once. The Jacobian columns are derivatives on that graph,
//! sharing its nodes. Three programs come out of it, all over the inputs
//! `(t, q_I⁽⁰⁾ … q_I⁽⁶⁾)`:
//!
//! * `value`: `D` (an iteration's evaluation);
//! * `solve`: `D`, `∂D/∂q⁗` and `∂E/∂q⃛` (a solve's Jacobian);
//! * `project`: `D`, `∂D/∂q⃛` and `∂D/∂q⁗` (a projection's Jacobian).
//!
//! They compute the same functions as the dual passes over [`Jet4`] they
//! replace (to round-off: the operations are grouped differently). A trace
//! holds at every state only if no operation decided a branch on a value
//! ([`Graph::is_exact`]): the embedding maps' arctangent records its branch
//! as one operation ([`nonholo_core::scene::atan2_near`]), but where a
//! scene's functions branch otherwise the trace is refused and the dual
//! passes stay. The branch of the map nearest to `near` is part of the
//! trace: a change of branch needs a new one.

use nonholo_core::graph::{Graph, Program, Tracer, trace};
use nonholo_core::scene::EmbeddingInfo;
use nonholo_core::{Scalar, Scene};

use crate::analysis::LEVELS;
use crate::elo::elo_array;
use crate::jet::Jet4;

/// The three programs of the [module docs](self) for one scene and branch.
#[derive(Debug, Clone)]
pub struct TracedArray {
    value: Program,
    solve: Program,
    project: Program,
}

/// Register files and outputs of the programs of a [`TracedArray`] over
/// `T` (`f64` on the real line, where the programs run as native code;
/// [`nonholo_core::complex::C64`] along a path in complex time, in the
/// interpreter): allocated once, reused by every evaluation.
#[derive(Debug, Clone)]
pub struct ArrayWorkspace<T = f64> {
    value: Vec<T>,
    solve: Vec<T>,
    project: Vec<T>,
    /// The outputs of the last program run.
    out: Vec<T>,
}

impl TracedArray {
    /// Traces `D` of `scene` at `(t, d)` (`d = (q_I⁽⁰⁾ … q_I⁽⁶⁾)`, `7m`
    /// numbers; the state only gives the trace its values) on the map's
    /// branch nearest to `near`. `Err` names the operations that depend on
    /// values where the trace would hold only near this state.
    pub fn new<S: Scene>(
        scene: &S,
        e: &EmbeddingInfo,
        t: f64,
        d: &[f64],
        near: &[f64],
    ) -> Result<TracedArray, String> {
        let m = e.independent.len();
        let rows = LEVELS * m;
        let inputs = 1 + 7 * m;
        let (mut g, outs) = trace(Graph::new(), || {
            let t = Tracer::input(0, t);
            let d: Vec<Tracer> = (0..7 * m)
                .map(|i| Tracer::input(1 + i as u32, d[i]))
                .collect();
            let mut out = vec![Tracer::from(0.0); rows];
            elo_array::<_, Tracer, Jet4<Tracer>>(scene, e, t, &d, near, &mut out);
            out.iter().map(|x| x.id).collect::<Vec<u32>>()
        });
        if let Some(what) = g.inexact() {
            return Err(format!("the derivative array depends on values ({what})"));
        }
        // Input of q⁽ᵏ⁾_j.
        let var = |k: usize, j: usize| (1 + k * m + j) as u32;
        let columns = |g: &mut Graph, k: usize, rows: &[u32]| -> Vec<u32> {
            (0..m)
                .flat_map(|j| rows.iter().map(move |&o| (j, o)))
                .map(|(j, o)| g.diff(o, var(k, j)))
                .collect()
        };
        let fourth = columns(&mut g, 4, &outs);
        let third_top = columns(&mut g, 3, &outs[..m]);
        let third = columns(&mut g, 3, &outs);
        let solve: Vec<u32> = [&outs[..], &fourth, &third_top].concat();
        let project: Vec<u32> = [&outs[..], &third, &fourth].concat();
        Ok(TracedArray {
            value: Program::new(&g, &outs, inputs),
            solve: Program::new(&g, &solve, inputs),
            project: Program::new(&g, &project, inputs),
        })
    }

    /// A workspace for this array's programs over `T`.
    pub fn workspace<T: Scalar>(&self) -> ArrayWorkspace<T> {
        let most = [&self.value, &self.solve, &self.project]
            .iter()
            .map(|p| p.shape().1)
            .max()
            .unwrap_or(0);
        ArrayWorkspace {
            value: self.value.registers(),
            solve: self.solve.registers(),
            project: self.project.registers(),
            out: vec![T::from(0.0); most],
        }
    }

    /// `D` at `(t, d)`: the `3m` values.
    pub fn value<'w, T: Scalar>(&self, w: &'w mut ArrayWorkspace<T>, t: T, d: &[T]) -> &'w [T] {
        run(&self.value, &mut w.value, &mut w.out, t, d)
    }

    /// `D` (`3m`), then `∂D/∂q⁗` column by column (`3m` each, `m` columns),
    /// then `∂E/∂q⃛` column by column (`m` each, `m` columns).
    pub fn solve<'w, T: Scalar>(&self, w: &'w mut ArrayWorkspace<T>, t: T, d: &[T]) -> &'w [T] {
        run(&self.solve, &mut w.solve, &mut w.out, t, d)
    }

    /// `D` (`3m`), then `∂D/∂q⃛` and `∂D/∂q⁗` column by column (`3m` each,
    /// `2m` columns).
    pub fn project<'w, T: Scalar>(&self, w: &'w mut ArrayWorkspace<T>, t: T, d: &[T]) -> &'w [T] {
        run(&self.project, &mut w.project, &mut w.out, t, d)
    }
}

/// Runs `p` at `(t, d)` with the register file `regs`; its outputs, at the
/// start of `out`.
fn run<'w, T: Scalar>(p: &Program, regs: &mut [T], out: &'w mut [T], t: T, d: &[T]) -> &'w [T] {
    let (inputs, outputs) = p.shape();
    regs[0] = t;
    regs[1..inputs].copy_from_slice(&d[..inputs - 1]);
    p.run(regs, &mut out[..outputs]);
    &out[..outputs]
}

#[cfg(test)]
mod tests {
    use super::*;
    use nonholo_core::{Params, Scene};
    use nonholo_scenes::{RollingDisk, Sleigh};
    use num_dual::{Dual2, Dual64};

    /// `D`, `∂D/∂q⁗`, `∂E/∂q⃛` and `∂D/∂q⃛` by dual passes over the jets,
    /// laid out as [`TracedArray::solve`] and [`TracedArray::project`]
    /// return them.
    fn by_dual_passes<S: Scene>(
        scene: &S,
        e: &EmbeddingInfo,
        t: f64,
        d: &[f64],
        near: &[f64],
    ) -> (Vec<f64>, Vec<f64>) {
        let m = e.independent.len();
        let rows = LEVELS * m;
        let column = |k: usize, j: usize| {
            let mut dd: Vec<Dual64> = d.iter().map(|&x| Dual64::from(x)).collect();
            dd[k * m + j].eps = 1.0;
            let mut out = vec![Dual64::from(0.0); rows];
            elo_array::<_, Dual64, Jet4<Dual64>>(scene, e, t.into(), &dd, near, &mut out);
            out
        };
        let value: Vec<f64> = column(4, 0).iter().map(|x| x.re).collect();
        let mut solve = value.clone();
        let mut project = value;
        for j in 0..m {
            solve.extend(column(4, j).iter().map(|x| x.eps));
        }
        for j in 0..m {
            let mut dd: Vec<Dual64> = d[..5 * m].iter().map(|&x| Dual64::from(x)).collect();
            dd[3 * m + j].eps = 1.0;
            let mut out = vec![Dual64::from(0.0); m];
            elo_array::<_, Dual64, Dual2<Dual64>>(scene, e, t.into(), &dd, near, &mut out);
            solve.extend(out.iter().map(|x| x.eps));
        }
        for k in [3, 4] {
            for j in 0..m {
                project.extend(column(k, j).iter().map(|x| x.eps));
            }
        }
        (solve, project)
    }

    /// States with the velocity `(ẋ, ẏ)` in every octant of the heading
    /// (where `atan2` takes other branches and formulas), the trace taken
    /// at the first.
    fn states(m: usize) -> Vec<Vec<f64>> {
        let headings = [0.3, 1.2, 2.0, 2.9, -2.9, -2.0, -1.2, -0.3];
        headings
            .iter()
            .map(|&h: &f64| {
                (0..7 * m)
                    .map(|i| match (i / m, i % m) {
                        (1, 0) => 1.7 * h.cos(),
                        (1, 1) => 1.7 * h.sin(),
                        (k, j) => 0.3 + 0.11 * (k * m + j) as f64 - 0.02 * (i * i) as f64,
                    })
                    .collect()
            })
            .collect()
    }

    /// The largest difference, relative to the largest output at the
    /// state, over [`states`]; each difference within `TOL` of it.
    fn check<S: Scene>(scene: &S, near: &[f64]) -> f64 {
        let mut worst = 0.0f64;
        let e = scene.info().embedding.expect("an embedding map");
        let m = e.independent.len();
        let all = states(m);
        let a = TracedArray::new(scene, &e, 0.0, &all[0], near).expect("traced");
        let mut w = a.workspace();
        for d in &all {
            let (solve, project) = by_dual_passes(scene, &e, 0.0, d, near);
            let scale = solve.iter().fold(1.0f64, |s, x| s.max(x.abs()));
            for (what, traced, dual) in [
                ("solve", a.solve(&mut w, 0.0, d).to_vec(), solve),
                ("project", a.project(&mut w, 0.0, d).to_vec(), project),
                (
                    "value",
                    a.value(&mut w, 0.0, d).to_vec(),
                    jet_value(scene, &e, d, near),
                ),
            ] {
                assert_eq!(traced.len(), dual.len(), "{what}");
                for (k, (x, y)) in traced.iter().zip(&dual).enumerate() {
                    worst = worst.max((x - y).abs() / scale);
                    assert!(
                        (x - y).abs() <= TOL * scale,
                        "{} {what} output {k} at {d:?} near {near:?}: traced {x}, dual passes {y}",
                        scene.info().name
                    );
                }
            }
        }
        worst
    }

    /// `D` by the order-4 jet over `f64`.
    fn jet_value<S: Scene>(scene: &S, e: &EmbeddingInfo, d: &[f64], near: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; LEVELS * e.independent.len()];
        elo_array::<_, f64, Jet4<f64>>(scene, e, 0.0, d, near, &mut out);
        out
    }

    /// The programs group the jets' operations differently: round-off,
    /// measured at most 1.4e-15 of the largest output over these states
    /// (about 6 ε); 1e-13 leaves room for another platform's `sin`, `atan`,
    /// while a wrong branch (a multiple of π/2 in an angle) or a trace that
    /// held only near its own state would differ by O(1).
    const TOL: f64 = 1e-13;

    /// The sleigh (both potentials) and the rolling disk trace exactly
    /// (their arctangent is one operation), and the traced programs equal
    /// the dual passes over the jets to round-off at headings in every
    /// octant, on the principal branch and on another one.
    #[test]
    fn traced_programs_equal_the_dual_passes_at_every_heading() {
        let mut worst = 0.0f64;
        for potential in ["paper", "com"] {
            let given = vec![("potential".to_string(), potential.to_string())];
            let params = Params::resolve(Sleigh::INFO.params, &given, "parameter").unwrap();
            let s = Sleigh::from_params(&params).unwrap();
            worst = worst.max(check(&s, &[])).max(check(&s, &[3.5]));
        }
        let disk = RollingDisk::from_params(&Params::defaults(RollingDisk::INFO.params)).unwrap();
        worst = worst.max(check(&disk, &[])).max(check(&disk, &[-3.0]));
        eprintln!(
            "traced against dual passes: largest difference {worst:.1e} of the largest output"
        );
    }
}
