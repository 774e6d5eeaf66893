//! The result schema of one run (`nonholo.run/1`, documented in
//! `docs/schema.md`).

use nonholo_core::integrate::{Radau5Options, Stats};
use nonholo_core::{CrossingRecord, Params, Run, RunStatus, SwitchRecord, Value};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value as Json};

use crate::table::{StateRow, Table, state_header};

/// Identifier of the run schema; bumped only for incompatible changes.
pub const RUN_SCHEMA: &str = "nonholo.run/1";

#[derive(Debug, Clone, Serialize)]
pub struct IntegratorRecord {
    pub method: String,
    pub rtol: f64,
    pub atol: f64,
    pub fixed_step: Option<f64>,
    pub max_steps: usize,
    pub max_wall_time_s: Option<f64>,
    /// Newton iteration of radau5 (`simplified` or `full`); absent for explicit methods.
    pub radau_newton: Option<String>,
    /// The remaining integrator settings (`nonholo_integrate::Options`), as given.
    pub atol_components: Option<Vec<f64>>,
    pub h_init: Option<f64>,
    pub h_max: Option<f64>,
    pub output: Vec<f64>,
    pub dense: bool,
    pub hit_output: bool,
    /// radau5's settings in their serde form; absent for explicit methods.
    pub radau5: Option<Radau5Options>,
    /// Whether an explicit run stops where its stiffness test keeps firing.
    pub stiff_stop: bool,
}

#[derive(Debug, Clone, Serialize)]
pub struct ProjectionRecord {
    pub q_before: Vec<f64>,
    pub q_dot_before: Vec<f64>,
    pub dq_norm: f64,
    pub dq_dot_norm: f64,
    pub velocity_residual_before: f64,
    pub velocity_residual_after: f64,
    pub position_residual_before: f64,
    pub position_residual_after: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct InitRecord {
    pub t0: f64,
    pub q: Vec<f64>,
    pub q_dot: Vec<f64>,
    /// Formulation-specific initial values (`lambda`, ...).
    pub extra: Map<String, Json>,
    /// What `--project-init` changed.
    pub projection: Option<ProjectionRecord>,
    /// What the formulation found setting up its initial state (A: `rank_w`,
    /// `hidden_constraints`, `free_initial_data`, …); empty for B and C.
    pub report: Map<String, Json>,
}

#[derive(Debug, Clone, Serialize)]
pub struct InvariantRecord {
    pub name: String,
    pub initial: f64,
    pub drift_max: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct DiagnosticsRecord {
    pub constraint_residual_max: f64,
    pub nonholonomic_residual_max: f64,
    pub holonomic_residual_max: f64,
    pub holonomic_velocity_residual_max: f64,
    pub energy_initial: f64,
    pub energy_final: f64,
    pub energy_drift_max: f64,
    pub invariants: Vec<InvariantRecord>,
    pub states_checked: usize,
}

impl From<&nonholo_core::Diagnostics> for DiagnosticsRecord {
    fn from(d: &nonholo_core::Diagnostics) -> Self {
        DiagnosticsRecord {
            constraint_residual_max: d.constraint_residual_max,
            nonholonomic_residual_max: d.nonholonomic_residual_max,
            holonomic_residual_max: d.holonomic_residual_max,
            holonomic_velocity_residual_max: d.holonomic_velocity_residual_max,
            energy_initial: d.energy_initial,
            energy_final: d.energy_final,
            energy_drift_max: d.energy_drift_max,
            invariants: d
                .invariants
                .iter()
                .map(|i| InvariantRecord {
                    name: i.name.clone(),
                    initial: i.initial,
                    drift_max: i.drift_max,
                })
                .collect(),
            states_checked: d.states_checked,
        }
    }
}

/// The work counters of one integration, as every result file reports them
/// (in this order).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Counters {
    pub steps: usize,
    pub rejected_steps: usize,
    pub rhs_evals: usize,
    pub jacobian_evals: usize,
    pub lu_decompositions: usize,
    pub newton_failures: usize,
}

impl From<&Stats> for Counters {
    fn from(st: &Stats) -> Self {
        Counters {
            steps: st.steps,
            rejected_steps: st.rejected_steps,
            rhs_evals: st.rhs_evals,
            jacobian_evals: st.jacobian_evals,
            lu_decompositions: st.lu_decompositions,
            newton_failures: st.newton_failures,
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct StatsRecord {
    #[serde(flatten)]
    pub counters: Counters,
    pub wall_time_s: f64,
    /// `[t, h·|λ|]` where the stiffness test of an explicit method fired.
    pub stiffness_detected: Option<[f64; 2]>,
}

#[derive(Debug, Clone, Serialize)]
pub struct ErrorRecord {
    pub t: Option<f64>,
    pub message: String,
}

/// One run, as written to `--out FILE.json`.
#[derive(Debug, Clone, Serialize)]
pub struct RunRecord {
    pub schema: &'static str,
    pub scene: String,
    pub formulation: String,
    pub integrator: IntegratorRecord,
    pub params: Map<String, Json>,
    pub options: Map<String, Json>,
    pub init: InitRecord,
    pub coordinates: Vec<String>,
    pub t: Vec<f64>,
    pub q: Vec<Vec<f64>>,
    pub q_dot: Vec<Vec<f64>>,
    /// What the multipliers mean (B and C use different conventions).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub multiplier_convention: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lambda: Option<Vec<Vec<f64>>>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub nu: Option<Vec<Vec<f64>>>,
    pub diagnostics: DiagnosticsRecord,
    pub stats: StatsRecord,
    /// The crossings of singular sets the run made, in order (empty for
    /// every formulation but A with a continuation).
    pub crossings: Vec<CrossingRecord>,
    /// The changes of mode the run made, in order (the friction
    /// realisation's stick–slip transitions; absent for formulations
    /// without modes).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub switches: Vec<SwitchRecord>,
    /// `completed` or `failed`.
    pub status: &'static str,
    pub error: Option<ErrorRecord>,
    /// Formulation A: how its initial derivatives were matched with C.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub matching: Option<crate::matching::MatchReport>,
    /// `nonholo bvp`: the boundary-value problem and how it was solved
    /// (docs/schema.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bvp: Option<crate::bvp::BvpRecord>,
}

/// The meaning of the multipliers a formulation reports.
pub fn multiplier_convention(formulation: &str) -> &'static str {
    match formulation {
        "chetaev" => "B: constraint forces, M q̈ − Q = Gᵀλ + Fᵀν",
        "vakonomic" => "C: multipliers of the action, L + λᵀg (state); holonomic ν as in B",
        _ => "see docs/formulations.md",
    }
}

/// `{name: value}` in spec order.
pub fn params_json(p: &Params) -> Map<String, Json> {
    p.iter()
        .map(|(spec, v)| {
            let j = match v {
                Value::Real(x) => Json::from(x),
                Value::Choice(c) => Json::from(c),
            };
            (spec.name.to_string(), j)
        })
        .collect()
}

impl RunRecord {
    /// The record of `run`. Refuses (with the column and time) if any number
    /// that would be written is not finite: JSON has no NaN, and a silent
    /// `null` in a result is worse than no result.
    pub fn from_run(run: &Run) -> Result<RunRecord, String> {
        let info = run.model.scene_info();
        let (s, k) = (info.s(), info.k());
        let names = run.model.multiplier_names();
        let has_multipliers = !names.is_empty();
        let t = run.solution.t[..run.samples.len()].to_vec();
        let q: Vec<Vec<f64>> = run.samples.iter().map(|o| o.q.clone()).collect();
        let q_dot: Vec<Vec<f64>> = run.samples.iter().map(|o| o.qd.clone()).collect();
        let lambda: Option<Vec<Vec<f64>>> = (has_multipliers && s > 0).then(|| {
            run.samples
                .iter()
                .map(|o| o.multipliers[..s].to_vec())
                .collect()
        });
        let nu: Option<Vec<Vec<f64>>> = (has_multipliers && k > 0).then(|| {
            run.samples
                .iter()
                .map(|o| o.multipliers[s..s + k].to_vec())
                .collect()
        });

        let check = |what: &str, rows: &[Vec<f64>]| -> Result<(), String> {
            for (i, r) in rows.iter().enumerate() {
                if let Some(j) = r.iter().position(|v| !v.is_finite()) {
                    return Err(format!(
                        "refusing to write a non-finite value: {what}[{j}] = {} at t = {}",
                        r[j], t[i]
                    ));
                }
            }
            Ok(())
        };
        check("q", &q)?;
        check("q_dot", &q_dot)?;
        let d = &run.diagnostics;
        let mut scalars: Vec<(String, f64)> = vec![
            (
                "diagnostics.constraint_residual_max".into(),
                d.constraint_residual_max,
            ),
            ("diagnostics.energy_initial".into(), d.energy_initial),
            ("diagnostics.energy_final".into(), d.energy_final),
            ("diagnostics.energy_drift_max".into(), d.energy_drift_max),
            ("stats.wall_time_s".into(), run.solution.stats.wall_time_s),
        ];
        for inv in &d.invariants {
            scalars.push((
                format!("diagnostics.invariants.{}.initial", inv.name),
                inv.initial,
            ));
            scalars.push((
                format!("diagnostics.invariants.{}.drift_max", inv.name),
                inv.drift_max,
            ));
        }
        for c in &run.crossings {
            for (name, v) in [
                ("t_singular", c.t_singular),
                ("clearance", c.clearance),
                ("gap_error", c.gap_error),
                ("return_residual", c.return_residual),
                ("restart_change", c.restart_change),
            ] {
                scalars.push((format!("crossings[{}].{name}", c.number), v));
            }
        }
        for (k, v) in run.model.init_report() {
            scalars.push((format!("init.report.{k}"), v));
        }
        scalars.extend(
            run.initial
                .q
                .iter()
                .chain(&run.initial.qd)
                .map(|v| ("init".to_string(), *v)),
        );
        if let Some((name, v)) = scalars.iter().find(|(_, v)| !v.is_finite()) {
            return Err(format!(
                "refusing to write a non-finite value: {name} = {v} (the state overflowed or \
                 left the domain of the scene's functions)"
            ));
        }
        if let Some(l) = &lambda {
            check("lambda", l)?;
        }
        if let Some(l) = &nu {
            check("nu", l)?;
        }

        let st = &run.solution.stats;
        let cfg = &run.config;
        Ok(RunRecord {
            schema: RUN_SCHEMA,
            scene: info.name.to_string(),
            formulation: run.model.formulation().name.to_string(),
            integrator: IntegratorRecord {
                method: cfg.method.name().to_string(),
                rtol: cfg.options.rtol,
                atol: cfg.options.atol,
                fixed_step: cfg.options.fixed_step,
                max_steps: cfg.options.max_steps,
                max_wall_time_s: cfg.options.max_wall_time_s,
                radau_newton: cfg
                    .method
                    .is_implicit()
                    .then(|| cfg.options.radau5.newton.name().to_string()),
                atol_components: cfg.options.atol_components.clone(),
                h_init: cfg.options.h_init,
                h_max: cfg.options.h_max,
                output: cfg.options.output.clone(),
                dense: cfg.options.dense,
                hit_output: cfg.options.hit_output,
                radau5: cfg.method.is_implicit().then_some(cfg.options.radau5),
                stiff_stop: cfg.options.stiff_stop,
            },
            params: params_json(run.model.scene_params()),
            options: params_json(run.model.options()),
            init: InitRecord {
                t0: run.initial.t0,
                q: run.initial.q.clone(),
                q_dot: run.initial.qd.clone(),
                extra: run
                    .initial
                    .extra
                    .iter()
                    .map(|(n, v)| (n.clone(), Json::from(*v)))
                    .collect(),
                projection: run.projection.as_ref().map(|ip| {
                    let p = &ip.projection;
                    ProjectionRecord {
                        q_before: ip.q_before.clone(),
                        q_dot_before: ip.qd_before.clone(),
                        dq_norm: p.dq_norm,
                        dq_dot_norm: p.dqd_norm,
                        velocity_residual_before: p.velocity_residual.0,
                        velocity_residual_after: p.velocity_residual.1,
                        position_residual_before: p.position_residual.0,
                        position_residual_after: p.position_residual.1,
                    }
                }),
                report: run
                    .model
                    .init_report()
                    .into_iter()
                    .map(|(k, v)| (k.to_string(), Json::from(v)))
                    .collect(),
            },
            coordinates: info
                .coordinates
                .iter()
                .map(|c| c.name.to_string())
                .collect(),
            t,
            q,
            q_dot,
            multiplier_convention: has_multipliers
                .then(|| multiplier_convention(run.model.formulation().name)),
            lambda,
            nu,
            diagnostics: DiagnosticsRecord::from(d),
            stats: StatsRecord {
                counters: Counters::from(st),
                wall_time_s: st.wall_time_s,
                stiffness_detected: st.stiffness_detected.map(|(a, b)| [a, b]),
            },
            crossings: run.crossings.clone(),
            switches: run.switches.clone(),
            // Schema run/1 (docs/schema.md) knows `completed` and `failed`
            // only: a stop by design is a `failed` run whose error says so.
            status: match run.status() {
                RunStatus::Completed => "completed",
                RunStatus::Stopped | RunStatus::Failed => "failed",
            },
            error: run.failure.as_ref().map(|e| ErrorRecord {
                t: e.time(),
                message: e.to_string(),
            }),
            matching: None,
            bvp: None,
        })
    }

    /// The record without the trajectory arrays: what a CSV file cannot carry
    /// (status, tolerances, options, diagnostics, counters), written beside it.
    pub fn metadata(&self) -> Json {
        let mut j = serde_json::to_value(self).unwrap_or(Json::Null);
        if let Json::Object(map) = &mut j {
            for key in ["t", "q", "q_dot", "lambda", "nu"] {
                map.remove(key);
            }
        }
        j
    }

    /// CSV: `t,<q names>,<q names>_dot,<multiplier names>`, one row per output time.
    pub fn to_csv(&self, multiplier_names: &[String]) -> Result<Vec<u8>, String> {
        let mut table = Table::new(state_header(
            self.coordinates.iter().map(String::as_str),
            multiplier_names.iter().cloned(),
        ))?;
        fn at(m: &Option<Vec<Vec<f64>>>, i: usize) -> &[f64] {
            m.as_ref().map_or(&[], |m| &m[i])
        }
        for i in 0..self.t.len() {
            table.push_state(&StateRow {
                t: self.t[i],
                q: &self.q[i],
                q_dot: &self.q_dot[i],
                more: &[at(&self.lambda, i), at(&self.nu, i)],
            })?;
        }
        table.into_bytes()
    }
}

/// Atomic writing of a result file (see [`crate::io`]).
pub use crate::io::write_atomic;
