//! One colour per formulation in every figure: B blue, A vermillion, C
//! bluish green, `visc` reddish purple, `mass` orange, `friction` sky blue
//! (`gauss`, which is B by another solver, B's blue), closed forms black
//! (Okabe & Ito's palette, [`crate::plot::Pen`]); the integrator sets the
//! dash (DOP853 solid, Radau IIA dashed, DOPRI5 dotted, RK4 long dashes).
//! Two lines of one plot that would get the same pen (A with two
//! continuations, say) are told apart by the next free dash.

use crate::plot::{Dash, Pen};

/// The palette index of a formulation's colour.
pub fn colour_of(formulation: &str) -> usize {
    match formulation {
        // Gauss's principle with equality rows is B computed by a conic
        // solver: B's colour (a figure with both tells them by dash).
        "chetaev" | "gauss" => 0,
        "embedding" => 1,
        "vakonomic" => 2,
        "visc" => 3,
        "mass" => 4,
        "friction" => 5,
        // Every registered formulation has its colour above (the palette's
        // seven are taken); a name outside the registry shares the closed
        // forms' black.
        super::spec::CLOSED_FORM => 6,
        _ => 6,
    }
}

/// The dash of an integrator.
pub fn dash_of(integrator: &str) -> Dash {
    match integrator {
        "radau5" => Dash::Dashed,
        "dopri5" => Dash::Dotted,
        "rk4" => Dash::LongDash,
        _ => Dash::Solid,
    }
}

/// The pen of every formulation line of `exp`, handed out in the
/// experiment's order (so that a line keeps its pen in all of its figures).
pub fn of_experiment(exp: &super::spec::Experiment) -> Vec<(String, Pen)> {
    let mut pens = Pens::default();
    exp.formulations
        .iter()
        .map(|f| {
            (
                f.label.clone(),
                pens.take(&f.formulation, &f.settings.integrator),
            )
        })
        .collect()
}

/// The pen of line `label` in [`of_experiment`]'s list.
pub fn find(pens: &[(String, Pen)], label: &str) -> Option<Pen> {
    pens.iter().find(|(l, _)| l == label).map(|(_, p)| *p)
}

/// The pens handed out in one plot.
#[derive(Debug, Default)]
pub struct Pens {
    used: Vec<Pen>,
}

impl Pens {
    /// The pen of a line of `formulation` integrated by `integrator`: its
    /// colour and dash, or the next dash not yet used in this plot with
    /// that colour.
    pub fn take(&mut self, formulation: &str, integrator: &str) -> Pen {
        let colour = colour_of(formulation);
        let first = dash_of(integrator);
        let start = Dash::ALL.iter().position(|d| *d == first).unwrap_or(0);
        let pen = (0..Dash::ALL.len())
            .map(|i| Pen {
                colour,
                dash: Dash::ALL[(start + i) % Dash::ALL.len()],
            })
            .find(|p| !self.used.contains(p))
            .unwrap_or(Pen {
                colour,
                dash: first,
            });
        self.used.push(pen);
        pen
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_formulation_keeps_its_colour_and_repeats_get_other_dashes() {
        let mut pens = Pens::default();
        let b = pens.take("chetaev", "dop853");
        let a1 = pens.take("embedding", "dop853");
        let a2 = pens.take("embedding", "dop853");
        let c = pens.take("vakonomic", "radau5");
        assert_eq!(
            b,
            Pen {
                colour: 0,
                dash: Dash::Solid
            }
        );
        assert_eq!(
            a1,
            Pen {
                colour: 1,
                dash: Dash::Solid
            }
        );
        assert_eq!(
            a2,
            Pen {
                colour: 1,
                dash: Dash::Dashed
            }
        );
        assert_eq!(
            c,
            Pen {
                colour: 2,
                dash: Dash::Dashed
            }
        );
        let mut other = Pens::default();
        assert_eq!(
            other.take("vakonomic", "radau5"),
            c,
            "the same in every plot"
        );
        let colours: Vec<usize> = [
            "chetaev",
            "embedding",
            "vakonomic",
            "visc",
            "mass",
            "friction",
            "closed-form",
        ]
        .iter()
        .map(|f| colour_of(f))
        .collect();
        let mut distinct = colours.clone();
        distinct.sort();
        distinct.dedup();
        assert_eq!(distinct.len(), colours.len(), "{colours:?}");
    }
}
