//! B and C as index-1 differential-algebraic systems with sparse
//! Jacobians, for Radau IIA on scenes whose size makes the ODE form's dense
//! Jacobian the cost of a step.
//!
//! The ODE form `q̈ = a(q, q̇)` solves the KKT system inside every
//! right-hand side, so `∂a/∂(q, q̇)` couples every coordinate with every
//! other (on a chain of bodies, moving one body changes every constraint
//! force): its Jacobian is dense, `(2n)²` entries. Here the KKT unknowns
//! are part of the state instead, `y = (q, v, w)` with `w = (q̈, μ_g, μ_f)`
//! (length `m = n + s + k`), and the equations are those of the KKT system
//! itself:
//!
//! ```text
//! q' − v = 0
//! v' − q̈ = 0
//! K(t, q, v) w − b(t, q, v) = 0,   K = [M Gᵀ Fᵀ; G 0 0; F 0 0],
//!                                  b = (Q, −ġ₀ − 2αg, −f̈₀ − 2αḟ − β²f)
//! ```
//!
//! (`α`, `β` the Baumgarte gains, zero without stabilisation). For C the
//! field is `L + λᵀg` and its multipliers are state too, `y = (q, v, λ, w)`
//! with `λ' − μ_g = 0` (C's ODE form takes `λ̇ = μ_g` from the same solve),
//! and `K`, `b` depend on `λ` as well. Either system has an algebraic part
//! solvable for `w` wherever `K` is regular: index 1, and the same motion
//! as the formulation's ODE form. Every entry of its Jacobian is local:
//! `∂(Kw − b)/∂w = K` is the KKT pattern, and `∂(Kw − b)/∂(q, v, λ)` has the
//! entries that the compiled program's dependencies allow
//! ([`Compiled::dependencies`]). That block is computed by forward
//! differentiation along a few seeded directions: columns are grouped so
//! that no two columns of a group share a row (greedy colouring, Curtis,
//! Powell & Reid 1974), and one pass of the program over `Dual64` per group
//! gives all of the group's columns. On a chain the number of groups does
//! not grow with its length, so a Jacobian costs a fixed number of
//! right-hand sides, and Radau IIA's iteration matrices, of the same
//! pattern plus `J'`, are factored sparse ([`ImplicitSystem::sparsity`]).

use std::sync::Arc;

use num_dual::Dual64;

use crate::compiled::{Compiled, KktSource, Pieces, Workspace};
use crate::consistency::{InitProjection, check_or_project_with};
use crate::init::{ExtraName, lambda_names, lambda0};
use crate::integrate::{ImplicitSystem, Method, Sparsity, SystemError};
use crate::kkt::{Ideal, Kkt};
use crate::model::{Description, FormulationInfo, Observation};
use crate::monitor::Diagnostics;
use crate::param::ParamSpec;
use crate::scene::{Augmented, Lagrangian, Scalar};
use crate::stab::{Stabilisation, StepHooks};
use crate::{Error, Initial, Model, Params, Scene};

/// The form B and C are integrated in (option `form`).
pub const FORM: ParamSpec = ParamSpec::choice(
    "form",
    &["ode", "dae"],
    "ode: q̈ (and C's λ̇) from one KKT solve per right-hand side, any integrator; dae: the \
     KKT unknowns (q̈ and the multipliers' part of the solve) in the state, an index-1 DAE \
     with sparse Jacobians, radau5 only (for large scenes, e.g. sleigh-train)",
);

/// The field of the KKT system, and with it where the multipliers of `g`
/// live.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    /// B: `L`; the multipliers are KKT unknowns (`μ_g = −λ`).
    Lagrangian,
    /// C: `L + λᵀg`, with `λ` in the state (`λ̇ = μ_g`).
    Augmented,
}

/// B or C on `scene` as the index-1 system of the [module docs](self), and
/// as a [`Model`] (`form = "dae"`): integrated by Radau IIA only; its
/// multipliers are read from the state; the same per-step diagnostics and
/// guard as the ODE form.
pub struct KktDae<S: Scene> {
    scene: S,
    options: Params,
    formulation: &'static FormulationInfo,
    field: Field,
    /// Multipliers in the state: `s` for C, 0 for B.
    np: usize,
    hooks: StepHooks,
    /// `y'(t0)` of the last [`Model::initial_state`].
    yp0: Vec<f64>,
    program: Arc<Compiled>,
    /// Baumgarte gains `(α, β)` of the constraint rows.
    gains: (f64, f64),
    stab: Stabilisation,
    n: usize,
    s: usize,
    k: usize,
    /// Entries `(row, column, source)` of `K`, both triangles.
    kkt: Vec<(u32, u32, KktSource)>,
    sparsity: Sparsity,
    /// Position in the `∂F/∂y` list where `K`'s entries start.
    kkt_at: usize,
    /// The `(q, v, λ)` columns of the algebraic rows, grouped by colour:
    /// `(position in the ∂F/∂y list, row of K)` for every entry of a
    /// column of that colour.
    groups: Vec<Vec<(usize, usize)>>,
    /// Colour of every `(q, v, λ)` column (`u32::MAX`: no entry).
    colour: Vec<u32>,
    real: Workspace<f64>,
    dual: Workspace<Dual64>,
    /// `(q, v, λ)` over `Dual64` for a seeded pass.
    seeded: Vec<Dual64>,
    /// `∂(Kw − b)` along one seed.
    tangent: Vec<f64>,
}

impl<S: Scene + Clone> Clone for KktDae<S> {
    fn clone(&self) -> Self {
        KktDae {
            scene: self.scene.clone(),
            options: self.options.clone(),
            formulation: self.formulation,
            field: self.field,
            np: self.np,
            hooks: self.hooks.clone(),
            yp0: self.yp0.clone(),
            program: self.program.clone(),
            gains: self.gains,
            stab: self.stab,
            n: self.n,
            s: self.s,
            k: self.k,
            kkt: self.kkt.clone(),
            sparsity: self.sparsity.clone(),
            kkt_at: self.kkt_at,
            groups: self.groups.clone(),
            colour: self.colour.clone(),
            real: self.program.workspace(),
            dual: self.program.workspace(),
            seeded: self.seeded.clone(),
            tangent: self.tangent.clone(),
        }
    }
}

/// `out = part(K) w − part(b)` for the pieces `pc`, where `part` takes the
/// value (residual) or the derivative part (a Jacobian column group).
#[allow(clippy::too_many_arguments)]
fn kkt_apply<T: Scalar>(
    pc: &Pieces<'_, T>,
    kkt: &[(u32, u32, KktSource)],
    (n, s): (usize, usize),
    (alpha, beta): (f64, f64),
    part: impl Fn(&T) -> f64,
    w: &[f64],
    out: &mut [f64],
) {
    let k = pc.f.len();
    for i in 0..n {
        out[i] = -part(&pc.force[i]);
    }
    for i in 0..s {
        out[n + i] = part(&pc.g_rate0[i]) + 2.0 * alpha * part(&pc.g[i]);
    }
    for i in 0..k {
        out[n + s + i] = part(&pc.f_accel0[i])
            + 2.0 * alpha * part(&pc.f_rate[i])
            + beta * beta * part(&pc.f[i]);
    }
    for &(r, c, src) in kkt {
        out[r as usize] += part(src.value(pc.outputs)) * w[c as usize];
    }
}

impl<S: Scene> KktDae<S> {
    /// The `formulation` (B's or C's info; its `options`, stabilisation
    /// none or Baumgarte: a projection has no place in this form) on
    /// `scene` with the KKT system of `field`. Compiles the scene's
    /// program; a scene whose trace is refused (it branches on values) has
    /// no DAE form.
    pub fn new(
        scene: S,
        options: Params,
        formulation: &'static FormulationInfo,
        field: Field,
    ) -> Result<Self, Error> {
        let hooks = StepHooks::new(&scene, &options)?;
        let stab = hooks.stab;
        let info = scene.info();
        let refuse = |reason: String| Error::NotApplicable {
            formulation: format!("{} (DAE form)", formulation.name),
            scene: info.name.into(),
            reason,
        };
        if stab == Stabilisation::Projection {
            return Err(refuse(
                "stab = \"projection\": the DAE form keeps the constraints through its \
                 algebraic equations; choose none or baumgarte"
                    .into(),
            ));
        }
        let (n, s, k) = (info.n(), info.s(), info.k());
        let np = match field {
            Field::Lagrangian => 0,
            Field::Augmented => s,
        };
        let program = match field {
            Field::Lagrangian => Compiled::new(&Lagrangian(&scene), 0, &scene),
            Field::Augmented => Compiled::new(&Augmented(&scene), s, &scene),
        }
        .map_err(|e| refuse(format!("it needs the scene compiled into one program: {e}")))?;
        let gains = stab.gains();
        let kkt = program.kkt_entries();

        // The (q, v, λ) columns each row of `Kw − b` depends on.
        let m = n + s + k;
        let deps = program.dependencies();
        let mut rows: Vec<Vec<u32>> = vec![Vec::new(); m];
        let mut add = |r: usize, d: &[u32]| rows[r].extend_from_slice(d);
        for i in 0..n {
            add(i, &deps.force[i]);
        }
        for i in 0..s {
            add(n + i, &deps.g_rate0[i]);
            if gains.0 != 0.0 {
                add(n + i, &deps.g[i]);
            }
        }
        for i in 0..k {
            add(n + s + i, &deps.f_accel0[i]);
            if gains.0 != 0.0 {
                add(n + s + i, &deps.f_rate[i]);
            }
            if gains.1 != 0.0 {
                add(n + s + i, &deps.f[i]);
            }
        }
        for &(r, _, src) in &kkt {
            add(r as usize, src.value::<Vec<u32>>(deps.outputs));
        }
        // Inputs 1..=n are q, n+1..=2n are q̇, 2n+1..=2n+np the field's
        // parameters λ: columns 0..2n+np of (q, v, λ).
        let d = 2 * n + np;
        let qv = |i: u32| (1..=d as u32).contains(&i).then(|| i as usize - 1);
        let rows: Vec<Vec<usize>> = rows
            .into_iter()
            .map(|mut r| {
                r.sort_unstable();
                r.dedup();
                r.into_iter().filter_map(qv).collect()
            })
            .collect();

        // ∂F/∂y: ∂(q' − v)/∂v, ∂(v' − q̈)/∂q̈, ∂(λ' − μ_g)/∂μ_g, K, then
        // the (q, v, λ) block; `w` starts at `d`.
        let mut jy: Vec<(usize, usize)> = Vec::new();
        jy.extend((0..n).map(|i| (i, n + i)));
        jy.extend((0..n).map(|i| (n + i, d + i)));
        jy.extend((0..np).map(|j| (2 * n + j, d + n + j)));
        let kkt_at = jy.len();
        jy.extend(
            kkt.iter()
                .map(|&(r, c, _)| (d + r as usize, d + c as usize)),
        );
        let mut cols: Vec<Vec<(usize, usize)>> = vec![Vec::new(); d];
        for (r, row) in rows.iter().enumerate() {
            for &c in row {
                cols[c].push((jy.len(), r));
                jy.push((d + r, c));
            }
        }
        let colour = colour_columns(&cols, &rows);
        let colours = colour
            .iter()
            .filter(|&&c| c != u32::MAX)
            .max()
            .map_or(0, |&c| c + 1);
        let mut groups = vec![Vec::new(); colours as usize];
        for (c, entries) in cols.iter().enumerate() {
            if colour[c] != u32::MAX {
                groups[colour[c] as usize].extend_from_slice(entries);
            }
        }
        let sparsity = Sparsity {
            jy,
            jyp: (0..d).map(|i| (i, i)).collect(),
        };
        Ok(KktDae {
            real: program.workspace(),
            dual: program.workspace(),
            scene,
            options,
            formulation,
            field,
            np,
            hooks,
            yp0: Vec::new(),
            program: Arc::new(program),
            gains,
            stab,
            n,
            s,
            k,
            kkt,
            sparsity,
            kkt_at,
            groups,
            colour,
            seeded: vec![Dual64::from(0.0); d],
            tangent: vec![0.0; m],
        })
    }

    /// `(n, s, k)` of the scene.
    pub fn dims(&self) -> (usize, usize, usize) {
        (self.n, self.s, self.k)
    }

    /// Column groups of a Jacobian: its passes of the program over `Dual64`.
    pub fn colours(&self) -> usize {
        self.groups.len()
    }

    /// Consistent initial data from positions, velocities and (C) the
    /// multipliers `λ` (empty for B): `w` from one KKT solve,
    /// `y = (q, q̇, λ, w)`, `y' = (q̇, q̈, μ_g, 0)` (C's `λ̇ = μ_g`; the
    /// algebraic components' derivatives are not part of the equations).
    pub fn initial(
        &self,
        t: f64,
        q: &[f64],
        qd: &[f64],
        lambda: &[f64],
    ) -> Result<(Vec<f64>, Vec<f64>), Error> {
        let (n, np) = (self.n, self.np);
        assert_eq!(
            lambda.len(),
            np,
            "one multiplier per row of g for C, none for B"
        );
        let mut kkt: Kkt<f64> = Kkt::for_scene(self.scene.info());
        kkt.use_program(self.program.clone());
        let (scene, rows) = (&self.scene, Ideal(self.stab));
        match self.field {
            Field::Lagrangian => kkt.solve(&Lagrangian(scene), &[], scene, &rows, t, q, qd),
            Field::Augmented => kkt.solve(&Augmented(scene), lambda, scene, &rows, t, q, qd),
        }
        .map_err(|e| Error::InconsistentInit {
            formulation: self.formulation.name,
            reason: format!("the KKT system at t = {t} is singular: {e}"),
        })?;
        let y = [q, qd, lambda, &kkt.sol].concat();
        let mut yp = vec![0.0; y.len()];
        yp[..n].copy_from_slice(qd);
        yp[n..2 * n].copy_from_slice(&kkt.sol[..n]);
        yp[2 * n..2 * n + np].copy_from_slice(&kkt.sol[n..n + np]);
        Ok((y, yp))
    }
}

/// Greedy colouring of the `(q, v, λ)` columns: no two columns of one colour
/// share a row. `cols[c]` lists `(_, row)` of column `c`, `rows[r]` the
/// columns of row `r`; columns without entries get `u32::MAX`.
fn colour_columns(cols: &[Vec<(usize, usize)>], rows: &[Vec<usize>]) -> Vec<u32> {
    let mut colour = vec![u32::MAX; cols.len()];
    // `taken[c] == j`: colour `c` is used by a neighbour of column `j`.
    let mut taken: Vec<usize> = Vec::new();
    for (j, entries) in cols.iter().enumerate() {
        if entries.is_empty() {
            continue;
        }
        for &(_, r) in entries {
            for &other in &rows[r] {
                let c = colour[other];
                if c != u32::MAX {
                    taken[c as usize] = j;
                }
            }
        }
        let c = taken.iter().position(|&t| t != j).unwrap_or(taken.len());
        if c == taken.len() {
            taken.push(usize::MAX);
        }
        colour[j] = c as u32;
    }
    colour
}

impl<S: Scene> ImplicitSystem for KktDae<S> {
    fn dim(&self) -> usize {
        2 * self.n + self.np + self.n + self.s + self.k
    }

    fn residual(
        &mut self,
        t: f64,
        y: &[f64],
        yp: &[f64],
        res: &mut [f64],
    ) -> Result<(), SystemError> {
        let (n, np) = (self.n, self.np);
        let (q, rest) = y.split_at(n);
        let (v, rest) = rest.split_at(n);
        let (lambda, w) = rest.split_at(np);
        for i in 0..n {
            res[i] = yp[i] - v[i];
            res[n + i] = yp[n + i] - w[i];
        }
        for j in 0..np {
            res[2 * n + j] = yp[2 * n + j] - w[n + j];
        }
        self.program.eval(&mut self.real, t, q, v, lambda);
        let pc = self.real.pieces(&self.program);
        kkt_apply(
            &pc,
            &self.kkt,
            (n, self.s),
            self.gains,
            |x| *x,
            w,
            &mut res[2 * n + np..],
        );
        Ok(())
    }

    fn jacobians(
        &mut self,
        t: f64,
        y: &[f64],
        _yp: &[f64],
        jy: &mut [f64],
        jyp: &mut [f64],
    ) -> Result<(), SystemError> {
        let (n, np) = (self.n, self.np);
        let (q, rest) = y.split_at(n);
        let (v, rest) = rest.split_at(n);
        let (lambda, w) = rest.split_at(np);
        jyp.fill(1.0);
        jy[..2 * n + np].fill(-1.0);
        // K at (q, v, λ): from the first seeded pass's values, or from a
        // pass of its own when no (q, v, λ) column has an entry.
        if self.groups.is_empty() {
            self.program.eval(&mut self.real, t, q, v, lambda);
            let pc = self.real.pieces(&self.program);
            for (x, &(_, _, src)) in jy[self.kkt_at..].iter_mut().zip(&self.kkt) {
                *x = *src.value(pc.outputs);
            }
        }
        // One seeded pass per colour.
        for (colour, group) in self.groups.iter().enumerate() {
            for (j, x) in self.seeded.iter_mut().enumerate() {
                let value = match j {
                    j if j < n => q[j],
                    j if j < 2 * n => v[j - n],
                    j => lambda[j - 2 * n],
                };
                let seed = if self.colour[j] == colour as u32 {
                    1.0
                } else {
                    0.0
                };
                *x = Dual64::new(value, seed);
            }
            let (qs, rest) = self.seeded.split_at(n);
            let (vs, ls) = rest.split_at(n);
            self.program
                .eval(&mut self.dual, Dual64::from(t), qs, vs, ls);
            let pc = self.dual.pieces(&self.program);
            if colour == 0 {
                for (x, &(_, _, src)) in jy[self.kkt_at..].iter_mut().zip(&self.kkt) {
                    *x = src.value(pc.outputs).re;
                }
            }
            let (s, gains) = (self.s, self.gains);
            kkt_apply(
                &pc,
                &self.kkt,
                (n, s),
                gains,
                |x| x.tangent(),
                w,
                &mut self.tangent,
            );
            for &(at, r) in group {
                jy[at] = self.tangent[r];
            }
        }
        Ok(())
    }

    fn sparsity(&self) -> Option<Sparsity> {
        Some(self.sparsity.clone())
    }

    /// The formulation's diagnostics and guard on `(q, q̇)`; no projection
    /// (refused).
    fn after_step(&mut self, t: f64, y: &mut [f64]) -> Result<bool, SystemError> {
        let n = self.n;
        let (q, rest) = y.split_at_mut(n);
        self.hooks.after_step(&self.scene, t, q, &mut rest[..n])
    }

    fn guard(&mut self, t: f64, y: &[f64]) -> Option<f64> {
        let n = self.n;
        self.hooks.guard(&self.scene, t, &y[..n], &y[n..2 * n])
    }

    fn guard_reason(&mut self, t: f64, y: &[f64]) -> String {
        let n = self.n;
        self.hooks
            .guard_reason(&self.scene, t, &y[..n], &y[n..2 * n])
    }

    fn component_name(&self, i: usize) -> String {
        let (n, s, d) = (self.n, self.s, 2 * self.n + self.np);
        let name = |j: usize| self.scene.info().coordinates[j].name;
        match i {
            i if i < n => name(i).to_string(),
            i if i < 2 * n => format!("d{}/dt", name(i - n)),
            i if i < d => format!("λ[{}]", i - 2 * n),
            i if i < d + n => format!("d²{}/dt²", name(i - d)),
            i if i < d + n + s => format!("μ_g[{}]", i - d - n),
            i => format!("μ_f[{}]", i - d - n - s),
        }
    }
}

impl<S: Scene> KktDae<S> {
    /// The formulation's name with the form, for messages.
    fn form_name(&self) -> &'static str {
        match self.field {
            Field::Lagrangian => "chetaev (form = \"dae\")",
            Field::Augmented => "vakonomic (form = \"dae\")",
        }
    }
}

impl<S: Scene> Model for KktDae<S> {
    fn describe(&self) -> Description<'_> {
        Description {
            scene: self.scene.info(),
            formulation: self.formulation,
            params: self.scene.params(),
            options: &self.options,
        }
    }

    fn implicit(&mut self) -> Option<&mut dyn ImplicitSystem> {
        Some(self)
    }

    /// Radau IIA only: the form has no explicit right-hand side.
    fn accepts(&self, method: Method) -> Result<(), Error> {
        if method.is_implicit() {
            return Ok(());
        }
        Err(Error::NoExplicitForm {
            formulation: self.form_name(),
            method: method.name(),
        })
    }

    fn make_consistent(
        &mut self,
        init: &mut Initial,
        project: bool,
    ) -> Result<Option<InitProjection>, Error> {
        check_or_project_with(&self.scene, init, project, Some(&self.program))
    }

    fn initial_state(&mut self, init: &Initial) -> Result<Vec<f64>, Error> {
        let lambda = match self.field {
            Field::Lagrangian => Vec::new(),
            Field::Augmented => lambda0(init, self.s),
        };
        let (y, yp) = self.initial(init.t0, &init.q, &init.qd, &lambda)?;
        self.yp0 = yp;
        self.hooks.start(&self.scene, init.t0, &init.q, &init.qd);
        Ok(y)
    }

    fn initial_slope(&mut self) -> Result<Vec<f64>, Error> {
        Ok(self.yp0.clone())
    }

    /// C's `λ(0)` (`lambda`, or `lambda1`, …), as its ODE form takes them.
    fn extra_init_names(&self) -> Vec<ExtraName> {
        match self.field {
            Field::Lagrangian => Vec::new(),
            Field::Augmented => lambda_names(self.s, "initial multiplier λ(0) of L + λᵀg"),
        }
    }

    /// `(q, q̇)` and the multipliers as the ODE form reports them: B's
    /// `λ = −μ_g`, C's `λ` from the state; then `ν = −μ_f`.
    fn observe(&mut self, _t: f64, y: &[f64], obs: &mut Observation) -> Result<(), SystemError> {
        let (n, np) = (self.n, self.np);
        let d = 2 * n + np;
        obs.q.copy_from_slice(&y[..n]);
        obs.qd.copy_from_slice(&y[n..2 * n]);
        let (state, solved) = obs.multipliers.split_at_mut(np);
        state.copy_from_slice(&y[2 * n..d]);
        for (m, v) in solved.iter_mut().zip(&y[d + n + np..]) {
            *m = -v;
        }
        Ok(())
    }

    fn diagnostics(&self) -> Diagnostics {
        self.hooks.diagnostics().clone()
    }

    fn no_state_chart(&self) -> Error {
        Error::NotApplicable {
            formulation: self.form_name().into(),
            scene: self.scene.info().name.into(),
            reason: "linearisation reads the state of the ODE form; the DAE form adds the KKT \
                     unknowns to it: use form = \"ode\""
                .into(),
        }
    }
}
