//! The scenes of the workbench and their registry.
//!
//! | name | coordinates | constraints | embedding (A) | closed form |
//! |---|---|---|---|---|
//! | `sleigh-incline` | x, y, φ | 1 linear nonholonomic | φ = atan2(ẏ, ẋ) | B, a = 0 |
//! | `rolling-disk` | x, y, θ, ψ | 2 linear nonholonomic | θ = atan2(ẏ, ẋ), ψ̇ = ±speed/R (ψ cyclic) | B |
//! | `appell-hamel` | x, y, z | 1 nonlinear nonholonomic | — | B |
//! | `pendulum` | x, y | 1 holonomic | — | — |
//! | `coin-incline` | x, y, ψ, θ, φ | 2 linear nonholonomic | — | — |
//! | `bicycle` | x, y, ψ, φ, θ, δ, θR, θF | 1 holonomic, 4 linear nonholonomic | — | — |
//! | `sleigh-train` | xᵢ, yᵢ, φᵢ for N sleighs | 2(N − 1) holonomic, N linear nonholonomic | — | — |
//!
//! Code that must work with any scene receives it through [`SceneVisitor`],
//! which is called with the concrete scene type so that everything
//! downstream is monomorphised (no dynamic dispatch in right-hand sides).

pub mod appell;
pub mod bicycle;
pub mod coin;
pub mod disk;
pub mod pendulum;
mod rigid;
pub mod sleigh;
pub mod trailer;

use nonholo_core::{Error, Params, Scene, SceneInfo};

pub use appell::AppellHamel;
pub use bicycle::Bicycle;
pub use coin::Coin;
pub use disk::RollingDisk;
pub use pendulum::Pendulum;
pub use sleigh::{Potential, Sleigh};
pub use trailer::Train;

/// The gravitational acceleration `g` (m/s², default 9.81, at least 0),
/// a parameter of every scene with weight.
pub(crate) const GRAVITY: nonholo_core::ParamSpec = nonholo_core::ParamSpec::real(
    "g",
    "m/s^2",
    9.81,
    nonholo_core::Bound::Inclusive(0.0),
    nonholo_core::Bound::Unbounded,
    "gravitational acceleration",
);

/// Every scene, in listing order.
pub const ALL: &[&SceneInfo] = &[
    &sleigh::INFO,
    &disk::INFO,
    &appell::INFO,
    &pendulum::INFO,
    &bicycle::INFO,
    &coin::INFO,
    &trailer::INFO,
];

/// Something to do with a scene of any type.
pub trait SceneVisitor {
    type Output;
    fn visit<S: Scene>(self, scene: S) -> Self::Output;
}

/// A built scene of one of the registered types.
#[derive(Debug, Clone)]
pub enum AnyScene {
    Sleigh(Sleigh),
    RollingDisk(RollingDisk),
    AppellHamel(AppellHamel),
    Pendulum(Pendulum),
    /// Boxed: its 26 parameters make it several times larger than the others.
    Bicycle(Box<Bicycle>),
    Coin(Coin),
    Train(Train),
}

impl AnyScene {
    pub fn info(&self) -> &'static SceneInfo {
        match self {
            AnyScene::Sleigh(s) => s.info(),
            AnyScene::RollingDisk(s) => s.info(),
            AnyScene::AppellHamel(s) => s.info(),
            AnyScene::Pendulum(s) => s.info(),
            AnyScene::Bicycle(s) => s.info(),
            AnyScene::Coin(s) => s.info(),
            AnyScene::Train(s) => s.info(),
        }
    }

    pub fn params(&self) -> &Params {
        match self {
            AnyScene::Sleigh(s) => s.params(),
            AnyScene::RollingDisk(s) => s.params(),
            AnyScene::AppellHamel(s) => s.params(),
            AnyScene::Pendulum(s) => s.params(),
            AnyScene::Bicycle(s) => s.params(),
            AnyScene::Coin(s) => s.params(),
            AnyScene::Train(s) => s.params(),
        }
    }

    /// Calls `v` with the concrete scene.
    pub fn visit<V: SceneVisitor>(self, v: V) -> V::Output {
        match self {
            AnyScene::Sleigh(s) => v.visit(s),
            AnyScene::RollingDisk(s) => v.visit(s),
            AnyScene::AppellHamel(s) => v.visit(s),
            AnyScene::Pendulum(s) => v.visit(s),
            AnyScene::Bicycle(s) => v.visit(*s),
            AnyScene::Coin(s) => v.visit(s),
            AnyScene::Train(s) => v.visit(s),
        }
    }
}

/// The description of scene `name`, or an error listing the valid names.
pub fn info(name: &str) -> Result<&'static SceneInfo, Error> {
    ALL.iter()
        .find(|i| i.name == name)
        .copied()
        .ok_or_else(|| Error::UnknownName {
            what: "scene".into(),
            name: name.into(),
            valid: ALL.iter().map(|i| i.name.to_string()).collect(),
        })
}

/// The parameters of scene `name` that change its description
/// ([`SceneInfo::structural`]; empty for an unknown name).
pub fn structural(name: &str) -> &'static [&'static str] {
    info(name).map_or(&[], |i| i.structural)
}

/// The description of scene `name` with these parameter overrides: the
/// registry's ([`info`]) unless a [`SceneInfo::structural`] parameter makes
/// it depend on them, then the built scene's.
pub fn describe(name: &str, params: &[(String, String)]) -> Result<&'static SceneInfo, Error> {
    let info = info(name)?;
    if info.structural.is_empty() {
        return Ok(info);
    }
    Ok(build(name, params)?.info())
}

/// Builds scene `name` from `name=value` parameter overrides.
pub fn build(name: &str, params: &[(String, String)]) -> Result<AnyScene, Error> {
    let info = info(name)?;
    let p = Params::resolve(info.params, params, "parameter")?;
    Ok(match info.name {
        "sleigh-incline" => AnyScene::Sleigh(Sleigh::from_params(&p)?),
        "rolling-disk" => AnyScene::RollingDisk(RollingDisk::from_params(&p)?),
        "appell-hamel" => AnyScene::AppellHamel(AppellHamel::from_params(&p)?),
        "pendulum" => AnyScene::Pendulum(Pendulum::from_params(&p)?),
        "bicycle" => AnyScene::Bicycle(Box::new(Bicycle::from_params(&p)?)),
        "coin-incline" => AnyScene::Coin(Coin::from_params(&p)?),
        "sleigh-train" => AnyScene::Train(Train::from_params(&p)?),
        other => unreachable!("scene `{other}` listed in ALL but not built"),
    })
}
