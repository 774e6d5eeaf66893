//! Core of `nonholo`: scenes, automatic differentiation of their pieces,
//! models (formulations bound to scenes) and runs.
//!
//! * [`scene`]: what a scene is — coordinates, parameters, one Lagrangian
//!   generic over a dual-number type, optional constraints, embedding map,
//!   closed form and invariants.
//! * [`ad`]: mass matrix, forces, constraint Jacobians and their time
//!   derivatives by automatic differentiation (scalar dual passes).
//! * [`graph`], [`compiled`]: the same pieces from the scene's functions
//!   traced once into an expression graph, differentiated on the graph and
//!   evaluated as one straight-line program (B and C use it where the
//!   trace holds at every state); [`jit`] compiles such programs to native
//!   code (feature `jit`, on by default).
//! * [`constraints`], [`project`]: constraint pieces at a state; projection
//!   onto the constraint manifold.
//! * [`kkt`]: the constrained-acceleration system of the formulations with
//!   multipliers; [`binding`]: a formulation's equations bound to a scene.
//! * [`complex`]: [`complex::C64`], a complex [`Scalar`] for evaluating and
//!   differentiating scene functions at complex states.
//! * [`model`], [`run`]: the formulation-independent view used by the lab.

pub mod ad;
pub mod binding;
pub mod compiled;
pub mod complex;
pub mod consistency;
pub mod constraints;
pub mod dae;
mod error;
pub mod graph;
pub mod guard;
pub mod init;
#[cfg(feature = "jit")]
pub mod jit;
pub mod kkt;
pub mod linalg;
pub mod model;
pub mod monitor;
pub mod param;
pub mod project;
pub mod quadrature;
pub mod run;
pub mod scene;
pub mod sparse;
pub mod stab;

pub use binding::{Binding, Equations, EvalError};
pub use complex::C64;
pub use error::{Error, Level, num};
pub use init::Initial;
pub use model::{
    CrossingRecord, Description, FormulationInfo, Model, Observation, StateChart, Switch,
    SwitchRecord,
};
pub use monitor::Diagnostics;
pub use param::{Bound, Kind, ParamSpec, Params, Value};
pub use run::{Run, RunConfig, RunStatus, simulate};
pub use scene::{ContactInfo, Named, Scalar, Scene, SceneInfo};

pub use nonholo_integrate as integrate;
