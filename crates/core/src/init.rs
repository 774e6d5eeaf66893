//! Initial data from names: coordinates, `<coord>_dot`, the scene's
//! convenience values, and names a formulation adds (`lambda`, ...).
//!
//! Resolution: positions are the scene defaults overridden by the given
//! coordinates. Velocities come from the scene's velocity chart (defaults
//! overridden by given chart values) when the scene has one, else from the
//! default `q̇0`; given `<coord>_dot` values then replace components. Giving
//! both chart values and `<coord>_dot` values is refused: the two ways of
//! stating the velocity would silently compete.

use crate::Error;
use crate::scene::Scene;

/// A formulation-specific initial value (`lambda`, `x_ddot`, …).
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraName {
    pub name: String,
    pub unit: &'static str,
    pub description: &'static str,
}

impl ExtraName {
    pub fn new(name: impl Into<String>, unit: &'static str, description: &'static str) -> Self {
        ExtraName {
            name: name.into(),
            unit,
            description,
        }
    }
}

/// Resolved initial data.
#[derive(Debug, Clone, PartialEq)]
pub struct Initial {
    pub t0: f64,
    pub q: Vec<f64>,
    pub qd: Vec<f64>,
    /// Values of formulation-specific names (`lambda`, `x_ddot`, ...), in the
    /// order given.
    pub extra: Vec<(String, f64)>,
}

impl Initial {
    /// Value of a formulation-specific name, if given.
    pub fn extra(&self, name: &str) -> Option<f64> {
        self.extra.iter().find(|(n, _)| n == name).map(|(_, v)| *v)
    }
}

/// The names of initial multipliers of `s` nonholonomic constraints,
/// `lambda` or `lambda1..s`, each with `description`.
pub fn lambda_names(s: usize, description: &'static str) -> Vec<ExtraName> {
    crate::model::multiplier_names(s, 0)
        .into_iter()
        .map(|n| ExtraName::new(n, "", description))
        .collect()
}

/// The initial multipliers `λ(0)` of `s` nonholonomic constraints from
/// `init` (named as by [`lambda_names`]), 0 where not given.
pub fn lambda0(init: &Initial, s: usize) -> Vec<f64> {
    crate::model::multiplier_names(s, 0)
        .iter()
        .map(|name| init.extra(name).unwrap_or(0.0))
        .collect()
}

/// Every name `--init` accepts for `scene`, given the formulation's extra names.
pub fn valid_names<S: Scene>(scene: &S, extra: &[String]) -> Vec<String> {
    let info = scene.info();
    let mut names: Vec<String> = info
        .coordinates
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    names.extend(info.coordinates.iter().map(|c| format!("{}_dot", c.name)));
    names.extend(info.velocity_chart.iter().map(|c| c.name.to_string()));
    names.extend(extra.iter().cloned());
    names
}

/// Parses one initial value; accepts a `deg` suffix for angles.
fn parse_value(name: &str, text: &str, unit: &str) -> Result<f64, Error> {
    let text_t = text.trim();
    let (number, scale) = match text_t.strip_suffix("deg") {
        Some(t) if unit == "rad" => (t.trim(), std::f64::consts::PI / 180.0),
        _ => (text_t, 1.0),
    };
    let x: f64 = number.parse().map_err(|_| Error::Parse {
        what: "initial value".into(),
        name: name.into(),
        value: text.into(),
        expected: "a real number".into(),
    })?;
    if !x.is_finite() {
        return Err(Error::OutOfRange {
            what: "initial value".into(),
            name: name.into(),
            value: text.into(),
            range: "(-inf, inf)".into(),
            description: "initial values must be finite".into(),
        });
    }
    Ok(x * scale)
}

/// Resolves `name=value` pairs into initial data for `scene`.
///
/// `extra` lists the names the formulation accepts beyond the physical ones
/// (e.g. `lambda`); they are returned in [`Initial::extra`]. Positions not
/// given start at [`Scene::default_q`], then [`Scene::place`] may move them
/// to fit the ones given; velocities follow from the positions.
pub fn resolve<S: Scene>(
    scene: &S,
    given: &[(String, String)],
    extra: &[ExtraName],
) -> Result<Initial, Error> {
    let info = scene.info();
    let n = info.n();
    let extra_names: Vec<String> = extra.iter().map(|e| e.name.clone()).collect();
    let mut q = scene.default_q();
    let mut chart = info.default_velocity.to_vec();
    let has_chart = !info.velocity_chart.is_empty();
    let mut q_given = vec![false; n];
    let mut qd_given: Vec<Option<f64>> = vec![None; n];
    let mut chart_given: Vec<&str> = Vec::new();
    let mut extra_values = Vec::new();
    let mut seen: Vec<&str> = Vec::new();

    for (name, text) in given {
        if seen.contains(&name.as_str()) {
            return Err(Error::Repeated {
                what: "initial value".into(),
                name: name.clone(),
            });
        }
        seen.push(name);
        if let Some(i) = info.coordinate_index(name) {
            q[i] = parse_value(name, text, info.coordinates[i].unit)?;
            q_given[i] = true;
        } else if let Some(i) = name
            .strip_suffix("_dot")
            .and_then(|c| info.coordinate_index(c))
        {
            qd_given[i] = Some(parse_value(name, text, "")?);
        } else if let Some(i) = info.velocity_chart.iter().position(|c| c.name == name) {
            chart[i] = parse_value(name, text, info.velocity_chart[i].unit)?;
            chart_given.push(info.velocity_chart[i].name);
        } else if let Some(e) = extra.iter().find(|e| &e.name == name) {
            extra_values.push((name.clone(), parse_value(name, text, e.unit)?));
        } else {
            return Err(Error::UnknownName {
                what: "initial value".into(),
                name: name.clone(),
                valid: valid_names(scene, &extra_names),
            });
        }
    }

    let raw: Vec<String> = qd_given
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_some())
        .map(|(i, _)| format!("{}_dot", info.coordinates[i].name))
        .collect();
    if !chart_given.is_empty() && !raw.is_empty() {
        return Err(Error::VelocitiesTwice {
            coordinates: info
                .coordinates
                .iter()
                .map(|c| format!("{}_dot", c.name))
                .collect(),
            chart: info.velocity_chart.iter().map(|c| c.name.into()).collect(),
            raw_given: raw,
            chart_given: chart_given.iter().map(|c| c.to_string()).collect(),
        });
    }

    scene.place(&mut q, &q_given);
    let mut qd = vec![0.0; n];
    if has_chart {
        scene.velocities_from(&q, &chart, &mut qd);
    } else {
        qd.copy_from_slice(&chart);
    }
    for (i, v) in qd_given.iter().enumerate() {
        if let Some(v) = v {
            qd[i] = *v;
        }
    }
    Ok(Initial {
        t0: 0.0,
        q,
        qd,
        extra: extra_values,
    })
}
