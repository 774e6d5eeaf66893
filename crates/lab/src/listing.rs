//! `nonholo scenes`: what each scene has and which formulations apply.

use nonholo_core::{Kind, SceneInfo};
use serde_json::{Value as Json, json};

use crate::formulations;

/// Applicability of every registered formulation to `info`: `(name, letter, Ok or reason)`.
pub fn applicability(info: &SceneInfo) -> Vec<(&'static str, &'static str, Result<(), String>)> {
    formulations::ALL
        .iter()
        .map(|f| (f.name, f.letter, (f.applicable)(info)))
        .collect()
}

/// Plain-text listing of every scene.
pub fn text() -> String {
    use std::fmt::Write;
    let mut s = String::new();
    for info in nonholo_scenes::ALL {
        let _ = writeln!(s, "{} — {}", info.name, info.title);
        let _ = writeln!(s, "  {}", info.description);
        let coords: Vec<String> = info
            .coordinates
            .iter()
            .map(|c| format!("{} [{}]", c.name, c.unit))
            .collect();
        let _ = writeln!(s, "  coordinates: {}", coords.join(", "));
        if !info.velocity_chart.is_empty() {
            let chart: Vec<String> = info
                .velocity_chart
                .iter()
                .map(|c| format!("{} [{}]: {}", c.name, c.unit, c.description))
                .collect();
            let _ = writeln!(s, "  velocities by: {}", chart.join("; "));
        }
        for c in info.nonholonomic {
            let _ = writeln!(
                s,
                "  nonholonomic constraint ({:?}): {c}",
                info.constraint_kind
            );
        }
        for c in info.holonomic {
            let _ = writeln!(s, "  holonomic constraint: {c}");
        }
        if let Some(e) = &info.embedding {
            let _ = writeln!(
                s,
                "  embedding map: {} — singular at {}",
                e.formula, e.singular_set
            );
        }
        if let Some(c) = &info.closed_form {
            let _ = writeln!(
                s,
                "  closed form: under {} when {}",
                c.formulation, c.conditions
            );
        }
        let _ = writeln!(s, "  parameters:");
        for p in info.params {
            let default = p.default.to_string();
            let unit = if p.unit.is_empty() {
                String::new()
            } else {
                format!(" [{}]", p.unit)
            };
            let _ = writeln!(
                s,
                "    {:<10}{unit} default {default}, range {} — {}",
                p.name,
                p.range_text(),
                p.description
            );
        }
        let _ = writeln!(s, "  formulations:");
        for (name, letter, ok) in applicability(info) {
            match ok {
                Ok(()) => {
                    let _ = writeln!(s, "    {letter} {name}: applies");
                }
                Err(why) => {
                    let _ = writeln!(s, "    {letter} {name}: not applicable — {why}");
                }
            }
        }
        s.push('\n');
    }
    s
}

/// The same listing as JSON, for scripts.
pub fn json() -> Json {
    let scenes: Vec<Json> = nonholo_scenes::ALL
        .iter()
        .map(|info| {
            json!({
                "name": info.name,
                "title": info.title,
                "description": info.description,
                "coordinates": info.coordinates.iter().map(|c| json!({"name": c.name, "unit": c.unit, "description": c.description})).collect::<Vec<_>>(),
                "velocity_chart": info.velocity_chart.iter().map(|c| json!({"name": c.name, "unit": c.unit, "description": c.description})).collect::<Vec<_>>(),
                "nonholonomic": info.nonholonomic,
                "holonomic": info.holonomic,
                "embedding": info.embedding.map(|e| json!({"formula": e.formula, "singular_set": e.singular_set})),
                "closed_form": info.closed_form.map(|c| json!({"formulation": c.formulation, "conditions": c.conditions})),
                "params": info.params.iter().map(|p| json!({
                    "name": p.name,
                    "unit": p.unit,
                    "default": p.default.to_string(),
                    "range": p.range_text(),
                    "choices": match p.kind { Kind::Choice(c) => Some(c), _ => None },
                    "description": p.description,
                })).collect::<Vec<_>>(),
                "formulations": applicability(info).into_iter().map(|(name, letter, ok)| json!({
                    "name": name,
                    "letter": letter,
                    "applicable": ok.is_ok(),
                    "reason": ok.err(),
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    Json::Array(scenes)
}
