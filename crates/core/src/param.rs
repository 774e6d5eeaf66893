//! Named values with units and ranges: scene parameters and formulation options.
//!
//! A [`ParamSpec`] says what a name means (unit, default, valid range,
//! description); [`Params`] is a complete set of resolved values, built from
//! the defaults and the `name=value` pairs a user gave, with every value
//! parsed and range-checked once, at the boundary.

use std::fmt;

use crate::Error;

/// One end of a real interval.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Bound {
    Unbounded,
    Inclusive(f64),
    Exclusive(f64),
}

/// What values a name accepts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// A real number in `[min, max]` (ends as given by the bounds).
    Real { min: Bound, max: Bound },
    /// One of a fixed list of words.
    Choice(&'static [&'static str]),
}

/// A resolved value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    Real(f64),
    Choice(&'static str),
}

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Value::Real(x) => write!(f, "{x}"),
            Value::Choice(s) => f.write_str(s),
        }
    }
}

/// Description of a named parameter or option.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSpec {
    pub name: &'static str,
    /// Unit, as plain text (`"m"`, `"rad"`, `"m^2"`, `"1/s"`, `""` for dimensionless).
    pub unit: &'static str,
    pub default: Value,
    pub kind: Kind,
    pub description: &'static str,
}

impl ParamSpec {
    /// A real parameter.
    pub const fn real(
        name: &'static str,
        unit: &'static str,
        default: f64,
        min: Bound,
        max: Bound,
        description: &'static str,
    ) -> Self {
        ParamSpec {
            name,
            unit,
            default: Value::Real(default),
            kind: Kind::Real { min, max },
            description,
        }
    }

    /// A choice among words; the first is the default.
    pub const fn choice(
        name: &'static str,
        choices: &'static [&'static str],
        description: &'static str,
    ) -> Self {
        ParamSpec {
            name,
            unit: "",
            default: Value::Choice(choices[0]),
            kind: Kind::Choice(choices),
            description,
        }
    }

    /// The valid range or choices, as text (`[0, 1.5708)`, `{paper, com}`).
    pub fn range_text(&self) -> String {
        match self.kind {
            Kind::Real { min, max } => {
                let lo = match min {
                    Bound::Unbounded => "(-inf".to_string(),
                    Bound::Inclusive(x) => format!("[{x}"),
                    Bound::Exclusive(x) => format!("({x}"),
                };
                let hi = match max {
                    Bound::Unbounded => "inf)".to_string(),
                    Bound::Inclusive(x) => format!("{x}]"),
                    Bound::Exclusive(x) => format!("{x})"),
                };
                format!("{lo}, {hi}")
            }
            Kind::Choice(c) => format!("{{{}}}", c.join(", ")),
        }
    }

    /// Parses `text` and checks it against the range; `what` names the kind
    /// of value in messages ("parameter", "option").
    ///
    /// Real values accept a `deg` suffix when the unit is `rad`.
    pub fn parse(&self, text: &str, what: &str) -> Result<Value, Error> {
        let text = text.trim();
        match self.kind {
            Kind::Real { .. } => {
                let (number, scale) = match text.strip_suffix("deg") {
                    Some(t) if self.unit == "rad" => (t.trim(), std::f64::consts::PI / 180.0),
                    _ => (text, 1.0),
                };
                let x: f64 = number.parse().map_err(|_| Error::Parse {
                    what: what.to_string(),
                    name: self.name.to_string(),
                    value: text.to_string(),
                    expected: format!(
                        "a real number{} in {}",
                        if self.unit == "rad" {
                            " (or degrees with a `deg` suffix)"
                        } else {
                            ""
                        },
                        self.range_text()
                    ),
                })?;
                let x = x * scale;
                // Report the value as typed (not `inf` for 1e400, not radians for `90deg`).
                self.check(Value::Real(x), what).map_err(|e| match e {
                    Error::OutOfRange {
                        what,
                        name,
                        range,
                        description,
                        ..
                    } => Error::OutOfRange {
                        what,
                        name,
                        value: text.to_string(),
                        range,
                        description,
                    },
                    other => other,
                })?;
                Ok(Value::Real(x))
            }
            Kind::Choice(choices) => choices
                .iter()
                .find(|c| **c == text)
                .map(|c| Value::Choice(c))
                .ok_or_else(|| Error::Parse {
                    what: what.to_string(),
                    name: self.name.to_string(),
                    value: text.to_string(),
                    expected: format!("one of {}", self.range_text()),
                }),
        }
    }

    /// Checks a value against the range.
    pub fn check(&self, value: Value, what: &str) -> Result<(), Error> {
        let out_of_range = || Error::OutOfRange {
            what: what.to_string(),
            name: self.name.to_string(),
            value: value.to_string(),
            range: self.range_text(),
            description: self.description.to_string(),
        };
        match (self.kind, value) {
            (Kind::Real { min, max }, Value::Real(x)) => {
                let above = match min {
                    Bound::Unbounded => x > f64::NEG_INFINITY,
                    Bound::Inclusive(m) => x >= m,
                    Bound::Exclusive(m) => x > m,
                };
                let below = match max {
                    Bound::Unbounded => x < f64::INFINITY,
                    Bound::Inclusive(m) => x <= m,
                    Bound::Exclusive(m) => x < m,
                };
                if x.is_finite() && above && below {
                    Ok(())
                } else {
                    Err(out_of_range())
                }
            }
            (Kind::Choice(c), Value::Choice(s)) if c.contains(&s) => Ok(()),
            _ => Err(out_of_range()),
        }
    }
}

/// A complete set of resolved values for a list of specs, in spec order.
#[derive(Debug, Clone, PartialEq)]
pub struct Params {
    specs: &'static [ParamSpec],
    values: Vec<Value>,
}

impl Params {
    /// All defaults.
    pub fn defaults(specs: &'static [ParamSpec]) -> Self {
        Params {
            specs,
            values: specs.iter().map(|s| s.default).collect(),
        }
    }

    /// Defaults overridden by `given` (`name`, `text`) pairs; `what` names the
    /// kind of value in messages. Unknown or repeated names are errors.
    pub fn resolve(
        specs: &'static [ParamSpec],
        given: &[(String, String)],
        what: &str,
    ) -> Result<Self, Error> {
        let mut params = Params::defaults(specs);
        let mut seen: Vec<&str> = Vec::new();
        for (name, text) in given {
            let i =
                specs
                    .iter()
                    .position(|s| s.name == name)
                    .ok_or_else(|| Error::UnknownName {
                        what: what.to_string(),
                        name: name.clone(),
                        valid: specs.iter().map(|s| s.name.to_string()).collect(),
                    })?;
            if seen.contains(&name.as_str()) {
                return Err(Error::Repeated {
                    what: what.to_string(),
                    name: name.clone(),
                });
            }
            seen.push(name);
            params.values[i] = specs[i].parse(text, what)?;
        }
        Ok(params)
    }

    pub fn specs(&self) -> &'static [ParamSpec] {
        self.specs
    }

    /// `(spec, value)` pairs in spec order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static ParamSpec, Value)> + '_ {
        self.specs.iter().zip(self.values.iter().copied())
    }

    pub fn get(&self, name: &str) -> Option<Value> {
        self.specs
            .iter()
            .position(|s| s.name == name)
            .map(|i| self.values[i])
    }

    /// The real value of `name`; [`Error::UnknownName`] if this set has no
    /// real parameter of that name.
    pub fn real(&self, name: &str) -> Result<f64, Error> {
        match self.get(name) {
            Some(Value::Real(x)) => Ok(x),
            _ => Err(self.unknown(name, "real parameter", |k| matches!(k, Kind::Real { .. }))),
        }
    }

    /// The word chosen for `name`; [`Error::UnknownName`] if this set has no
    /// choice parameter of that name.
    pub fn choice(&self, name: &str) -> Result<&'static str, Error> {
        match self.get(name) {
            Some(Value::Choice(c)) => Ok(c),
            _ => Err(self.unknown(name, "choice parameter", |k| matches!(k, Kind::Choice(_)))),
        }
    }

    /// `name` is not a parameter of this set of the kind asked for: the
    /// names that are.
    fn unknown(&self, name: &str, what: &str, kind: impl Fn(Kind) -> bool) -> Error {
        Error::UnknownName {
            what: what.to_string(),
            name: name.to_string(),
            valid: self
                .specs
                .iter()
                .filter(|s| kind(s.kind))
                .map(|s| s.name.to_string())
                .collect(),
        }
    }

    /// Sets `name` to `value` after checking it against the range.
    pub fn set(&mut self, name: &str, value: Value, what: &str) -> Result<(), Error> {
        let i = self
            .specs
            .iter()
            .position(|s| s.name == name)
            .ok_or_else(|| Error::UnknownName {
                what: what.to_string(),
                name: name.to_string(),
                valid: self.specs.iter().map(|s| s.name.to_string()).collect(),
            })?;
        self.specs[i].check(value, what)?;
        self.values[i] = value;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const SPECS: &[ParamSpec] = &[
        ParamSpec::real(
            "alpha",
            "rad",
            0.3,
            Bound::Inclusive(0.0),
            Bound::Exclusive(std::f64::consts::FRAC_PI_2),
            "slope",
        ),
        ParamSpec::choice("potential", &["paper", "com"], "which potential"),
    ];

    fn given(pairs: &[(&str, &str)]) -> Vec<(String, String)> {
        pairs
            .iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect()
    }

    #[test]
    fn resolves_defaults_and_overrides() {
        let p = Params::resolve(SPECS, &given(&[("potential", "com")]), "parameter").unwrap();
        assert_eq!(p.real("alpha"), Ok(0.3));
        assert_eq!(p.choice("potential"), Ok("com"));
        let p = Params::resolve(SPECS, &given(&[("alpha", "30deg")]), "parameter").unwrap();
        assert!((p.real("alpha").unwrap() - std::f64::consts::PI / 6.0).abs() < 1e-15);
    }

    /// Asking for a name the set does not have, or a real as a choice, is an
    /// error naming the parameters of that kind, never a panic.
    #[test]
    fn access_by_a_wrong_name_or_kind_is_an_error() {
        let p = Params::defaults(SPECS);
        let e = p.real("alhpa").unwrap_err();
        assert_eq!(
            e,
            Error::UnknownName {
                what: "real parameter".into(),
                name: "alhpa".into(),
                valid: vec!["alpha".into()],
            }
        );
        assert!(
            matches!(p.choice("alpha"), Err(Error::UnknownName { valid, .. }) if valid == ["potential"])
        );
        assert!(p.real("potential").is_err());
    }

    #[test]
    fn messages_name_the_parameter_value_and_range() {
        let e = Params::resolve(SPECS, &given(&[("alpha", "2")]), "parameter").unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("alpha") && m.contains('2') && m.contains("[0, 1.57"),
            "{m}"
        );
        let m = Params::resolve(SPECS, &given(&[("alpha", "abc")]), "parameter")
            .unwrap_err()
            .to_string();
        assert!(
            m.contains("alpha") && m.contains("abc") && m.contains("real number"),
            "{m}"
        );
        let m = Params::resolve(SPECS, &given(&[("beta", "1")]), "parameter")
            .unwrap_err()
            .to_string();
        assert!(m.contains("beta") && m.contains("alpha, potential"), "{m}");
        let m = Params::resolve(SPECS, &given(&[("potential", "cm")]), "parameter")
            .unwrap_err()
            .to_string();
        assert!(m.contains("{paper, com}") && m.contains("cm"), "{m}");
        let m = Params::resolve(SPECS, &given(&[("alpha", "NaN")]), "parameter")
            .unwrap_err()
            .to_string();
        assert!(m.contains("NaN") && m.contains("outside"), "{m}");
        let m = Params::resolve(
            SPECS,
            &given(&[("alpha", "0.1"), ("alpha", "0.2")]),
            "parameter",
        )
        .unwrap_err()
        .to_string();
        assert!(m.contains("alpha") && m.contains("more than once"), "{m}");
    }
}
