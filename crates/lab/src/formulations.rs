//! The registry of formulations: names, applicability, construction.

use nonholo_core::{Error, FormulationInfo, Model, Params, Scene};
use nonholo_scenes::{AnyScene, SceneVisitor};

/// Every formulation this build has, in listing order.
pub const ALL: &[&FormulationInfo] = &[
    &nonholo_embedding::INFO,
    &nonholo_chetaev::INFO,
    &nonholo_vakonomic::INFO,
    &nonholo_realise::visc::INFO,
    &nonholo_realise::mass::INFO,
    &nonholo_contact::gauss::INFO,
    &nonholo_contact::friction::INFO,
];

/// The formulation called `name`, or an error listing the valid names.
pub fn info(name: &str) -> Result<&'static FormulationInfo, Error> {
    if let Some(f) = ALL.iter().find(|f| f.name == name) {
        return Ok(f);
    }
    Err(Error::UnknownName {
        what: "formulation".into(),
        name: name.into(),
        valid: ALL.iter().map(|f| f.name.to_string()).collect(),
    })
}

/// Refuses Radau IIA's Hermite dense output where Radau IIA would integrate
/// the model's implicit form `F(t, y, y') = 0` (the extension interpolates
/// the derivatives of `y' = f(t, y)`): checked with the input, not at the
/// first step of the run.
pub fn check_radau_dense(
    model: &mut dyn Model,
    method: nonholo_core::integrate::Method,
    options: &nonholo_core::integrate::Options,
) -> Result<(), String> {
    use nonholo_core::integrate::RadauDense;
    if method.is_implicit()
        && options.radau5.dense_output == RadauDense::Hermite
        && model.implicit().is_some()
    {
        return Err(format!(
            "radau_dense = hermite interpolates the derivatives of y' = f(t, y), and Radau \
             IIA integrates `{}` in its implicit form F(t, y, y') = 0: use auto or collocation",
            model.describe().formulation.name
        ));
    }
    Ok(())
}

/// Binds formulation `name` with `options` (`name=value` pairs) to `scene`.
pub fn build_model(
    scene: AnyScene,
    name: &str,
    options: &[(String, String)],
) -> Result<Box<dyn Model>, Error> {
    let f = info(name)?;
    let info = scene.info();
    (f.applicable)(info).map_err(|reason| Error::NotApplicable {
        formulation: f.name.into(),
        scene: info.name.into(),
        reason,
    })?;
    let options = Params::resolve(f.options, options, &format!("option of `{}`", f.name))?;
    scene.visit(Build {
        formulation: f,
        options,
    })
}

struct Build {
    formulation: &'static FormulationInfo,
    options: Params,
}

impl SceneVisitor for Build {
    type Output = Result<Box<dyn Model>, Error>;

    fn visit<S: Scene>(self, scene: S) -> Self::Output {
        match self.formulation.name {
            "chetaev" => nonholo_chetaev::model(scene, self.options),
            "vakonomic" => nonholo_vakonomic::model(scene, self.options),
            "embedding" => Ok(Box::new(nonholo_embedding::Embedding::new(
                scene,
                self.options,
            )?)),
            "visc" => Ok(Box::new(nonholo_realise::Visc::new(scene, self.options)?)),
            "mass" => Ok(Box::new(nonholo_realise::Mass::new(scene, self.options)?)),
            "gauss" => Ok(Box::new(nonholo_contact::gauss::Gauss::new(
                scene,
                self.options,
            )?)),
            "friction" => Ok(Box::new(nonholo_contact::friction::Friction::new(
                scene,
                self.options,
            )?)),
            other => unreachable!("formulation `{other}` registered but not constructed"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every registered formulation is constructed for every scene it
    /// declares itself applicable to (with the options it requires:
    /// friction's coefficient and normal load), and refused with a reason
    /// otherwise.
    #[test]
    fn registry_builds_every_applicable_pair() {
        for scene in nonholo_scenes::ALL {
            for f in ALL {
                let required: Vec<(String, String)> = match f.name {
                    "friction" => vec![
                        ("mu".into(), "0.5".into()),
                        ("normal".into(), "9.81".into()),
                    ],
                    _ => Vec::new(),
                };
                let built = nonholo_scenes::build(scene.name, &[])
                    .and_then(|s| build_model(s, f.name, &required));
                match (f.applicable)(scene) {
                    Ok(()) => assert!(
                        built.is_ok(),
                        "{} on {}: {:?}",
                        f.name,
                        scene.name,
                        built.err()
                    ),
                    Err(_) => assert!(matches!(built, Err(Error::NotApplicable { .. }))),
                }
            }
        }
    }
}
