//! Every committed figure, read from its SVG twin: the drawn data (curves
//! and their dots) stay inside the plot frame, and no curve runs through a
//! legend box placed inside the plot. (The PNG is rendered from the same
//! drawing calls; `tests/plot.rs` checks its pixels for the miter spikes
//! only the bitmap backend had.)

use std::path::{Path, PathBuf};

fn svgs(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap().filter_map(Result::ok) {
        let p = e.path();
        if p.is_dir() {
            svgs(&p, out);
        } else if p.extension().is_some_and(|x| x == "svg")
            && p.parent()
                .and_then(Path::file_name)
                .is_some_and(|n| n == "plots")
        {
            out.push(p);
        }
    }
}

/// The value of attribute `name` in the element text `el`.
fn attr<'a>(el: &'a str, name: &str) -> Option<&'a str> {
    let key = format!(" {name}=\"");
    let a = el.find(&key)? + key.len();
    let b = a + el[a..].find('"')?;
    Some(&el[a..b])
}

fn num(el: &str, name: &str) -> f64 {
    attr(el, name)
        .and_then(|v| v.parse().ok())
        .unwrap_or(f64::NAN)
}

/// Every element `<tag …>` of `svg`, as text.
fn elements<'a>(svg: &'a str, tag: &str) -> Vec<&'a str> {
    let open = format!("<{tag} ");
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find(&open) {
        let end = rest[i..].find('>').map(|j| i + j + 1).unwrap_or(rest.len());
        out.push(&rest[i..end]);
        rest = &rest[end..];
    }
    out
}

#[derive(Clone, Copy, Debug)]
struct Rect {
    x0: f64,
    y0: f64,
    x1: f64,
    y1: f64,
}

impl Rect {
    fn of(el: &str) -> Rect {
        let (x, y) = (num(el, "x"), num(el, "y"));
        Rect {
            x0: x,
            y0: y,
            x1: x + num(el, "width"),
            y1: y + num(el, "height"),
        }
    }
    fn contains(&self, (x, y): (f64, f64), slack: f64) -> bool {
        x >= self.x0 - slack && x <= self.x1 + slack && y >= self.y0 - slack && y <= self.y1 + slack
    }
}

#[test]
fn data_stay_in_the_frame_and_off_the_legend() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../results");
    let mut files = Vec::new();
    svgs(&root, &mut files);
    assert!(files.len() > 100, "{} figures", files.len());
    let mut checked = 0;
    let mut faults = Vec::new();
    for f in &files {
        let svg = std::fs::read_to_string(f).unwrap();
        // The plot frame: the first unfilled black rectangle (line plots).
        let Some(frame) = elements(&svg, "rect")
            .into_iter()
            .find(|r| attr(r, "fill") == Some("none") && attr(r, "stroke") == Some("#000000"))
            .map(Rect::of)
        else {
            continue;
        };
        let legend = elements(&svg, "rect")
            .into_iter()
            .find(|r| attr(r, "opacity") == Some("0.88") && attr(r, "fill") == Some("#FFFFFF"))
            .map(Rect::of);
        // Data curves are drawn 3 px wide (axes 2 px, grid 1 px).
        for line in elements(&svg, "polyline")
            .into_iter()
            .filter(|l| attr(l, "stroke-width") == Some("3"))
        {
            let pts: Vec<(f64, f64)> = attr(line, "points")
                .unwrap_or("")
                .split_whitespace()
                .filter_map(|p| {
                    let (x, y) = p.split_once(',')?;
                    Some((x.parse().ok()?, y.parse().ok()?))
                })
                .collect();
            // A legend's own sample line lies inside its box, or (a legend
            // beside or under the plot) wholly right of or below the frame.
            if legend.is_some_and(|l| pts.iter().all(|p| l.contains(*p, 1.0)))
                || pts
                    .iter()
                    .all(|p| p.0 > frame.x1 + 2.0 || p.1 > frame.y1 + 2.0)
            {
                continue;
            }
            let mut along = Vec::new();
            for w in pts.windows(2) {
                let (a, b) = (w[0], w[1]);
                let n = ((b.0 - a.0).hypot(b.1 - a.1)).ceil().max(1.0) as usize;
                along.extend((0..=n).map(|i| {
                    let t = i as f64 / n as f64;
                    (a.0 + t * (b.0 - a.0), a.1 + t * (b.1 - a.1))
                }));
            }
            along.extend(pts.first().copied());
            if let Some(p) = along.iter().find(|p| !frame.contains(**p, 2.0)) {
                faults.push(format!(
                    "{}: a curve leaves the frame at {p:?}",
                    f.display()
                ));
            }
            if let Some(l) = legend
                && let Some(p) = along.iter().find(|p| l.contains(**p, -1.0))
            {
                faults.push(format!(
                    "{}: a curve runs under the legend at {p:?}",
                    f.display()
                ));
            }
        }
        for c in elements(&svg, "circle") {
            let p = (num(c, "cx"), num(c, "cy"));
            if legend.is_some_and(|l| l.contains(p, 0.0)) {
                continue;
            }
            if !frame.contains(p, 2.0) && !legend.is_some_and(|l| l.contains(p, 1.0)) {
                // Dots of an outside legend sit beside the frame: only those
                // right of it or below it, on a legend row, are allowed.
                let beside = p.0 > frame.x1 || p.1 > frame.y1;
                if !beside {
                    faults.push(format!("{}: a dot outside the frame at {p:?}", f.display()));
                }
            }
        }
        checked += 1;
    }
    assert!(checked > 80, "{checked} line plots checked");
    assert!(
        faults.is_empty(),
        "{} faults:\n{}",
        faults.len(),
        faults.join("\n")
    );
}
