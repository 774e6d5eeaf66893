//! `index.html`: the page of an experiment (either kind): title, the
//! figure that stands for it (the one docs/figures.md cites), the claim,
//! how to reproduce it (command, experiment file, the figures page),
//! description, links to the result files, tables (numbers to four
//! significant digits; the files keep every digit), and every other figure
//! with its caption.
//!
//! Pages in the default results directory (`results/<name>`) also link to
//! `results/index.html`, the list of every result page there, which each
//! page rewrites when it is written ([`write_index`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::files::write;
use super::spec::Experiment;
use crate::table::escape;

/// The content of an experiment's page, in the order it is shown.
pub struct Page<'a> {
    pub exp: &'a Experiment,
    /// HTML opening the paragraph that links the files (may be empty).
    pub overview: String,
    /// Result files linked from the page, relative to it.
    pub files: &'a [&'a str],
    /// Sections before the figures: heading and HTML.
    pub before: Vec<(String, String)>,
    /// The figures (PNG files are shown; other formats are left out).
    pub plots: &'a [PathBuf],
    /// A figure's caption from its file stem.
    pub caption: &'a dyn Fn(&str) -> String,
    /// Sections after the figures: heading and HTML.
    pub after: Vec<(String, String)>,
}

impl Page<'_> {
    /// The page as HTML; figure paths are made relative to `dir`.
    pub fn html(&self, dir: &Path) -> String {
        let exp = self.exp;
        let mut h = String::new();
        let _ = write!(
            h,
            "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{}</title>\n\
             <style>body{{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}}\
             table{{border-collapse:collapse;font-size:0.8em}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}\
             figure{{margin:1.5em 0}}img{{max-width:100%}}figcaption{{color:#333}}</style></head><body>\n",
            escape(&exp.title)
        );
        let figure = |h: &mut String, p: &Path| {
            let rel = p.strip_prefix(dir).unwrap_or(p).display().to_string();
            let stem = p
                .file_stem()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_default();
            h.push_str(&figure_html(&rel, &stem, &(self.caption)(&stem)));
        };
        let _ = writeln!(h, "<h1>{}</h1>", escape(&exp.title));
        let main = super::cli::main_plot(exp, dir).filter(|m| self.plots.contains(m));
        if let Some(m) = &main {
            figure(&mut h, m);
        }
        let _ = writeln!(h, "<p><b>Claim tested:</b> {}</p>", escape(&exp.claim));
        let file = exp
            .path
            .file_name()
            .map(|f| f.to_string_lossy().to_string())
            .unwrap_or_default();
        let mut how = format!(
            "<p><b>Reproduce:</b> <code>nonholo experiment experiments/{}</code> (the \
             <a href=\"{}\">experiment file</a>)",
            escape(&file),
            escape(&super::cli::relative(dir, &exp.path))
        );
        let figures = exp
            .path
            .parent()
            .and_then(Path::parent)
            .map(|root| root.join("docs/figures.md"))
            .filter(|f| f.exists());
        if let Some(f) = figures {
            let _ = write!(
                how,
                "; every figure with its claim: <a href=\"{}\">docs/figures.md</a>",
                escape(&super::cli::relative(dir, &f))
            );
        }
        let _ = writeln!(h, "{how}.</p>");
        if in_results(exp, dir) {
            let _ = writeln!(
                h,
                "<p>Other experiments: <a href=\"../index.html\">every result page</a>.</p>"
            );
        }
        if !exp.description.is_empty() {
            let _ = writeln!(h, "<p>{}</p>", escape(&exp.description));
        }
        let links: Vec<String> = self
            .files
            .iter()
            .map(|f| format!("<a href=\"{f}\">{f}</a>"))
            .collect();
        let lead = if self.overview.is_empty() {
            String::new()
        } else {
            format!("{} ", self.overview)
        };
        let _ = writeln!(h, "<p>{lead}Files: {}.</p>", links.join(", "));
        let section = |h: &mut String, (title, body): &(String, String)| {
            // Wide tables scroll inside their box instead of widening the page.
            let _ = write!(
                h,
                "<h2>{}</h2>\n<div style=\"overflow-x:auto\">{body}</div>",
                escape(title)
            );
        };
        for s in &self.before {
            section(&mut h, s);
        }
        for p in self
            .plots
            .iter()
            .filter(|p| p.extension().is_some_and(|e| e == "png"))
            .filter(|p| main.as_ref() != Some(*p))
        {
            figure(&mut h, p);
        }
        for s in &self.after {
            section(&mut h, s);
        }
        let _ = writeln!(h, "</body></html>");
        h
    }

    /// Writes the page to `dir/index.html`, and the list of result pages
    /// beside it when `dir` is the default results directory.
    pub fn write(&self, dir: &Path) -> Result<(), String> {
        write(&dir.join("index.html"), self.html(dir).as_bytes())?;
        match dir.parent() {
            Some(root) if in_results(self.exp, dir) => write_index(root),
            _ => Ok(()),
        }
    }
}

/// A figure of a result page: the image at `src` (relative to the page),
/// `alt` text and caption, escaped.
pub fn figure_html(src: &str, alt: &str, caption: &str) -> String {
    format!(
        "<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>\n",
        escape(src),
        escape(alt),
        escape(caption)
    )
}

/// `dir` is `results/<name>` of `exp` (not a `--out` elsewhere).
fn in_results(exp: &Experiment, dir: &Path) -> bool {
    let canonical = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    canonical(dir) == canonical(&super::default_dir(exp))
}

/// Title and claim of the result page in `sub`: from its `summary.json`
/// (experiments), else the page's own `<title>` (e.g. `results/peers`).
fn describe(sub: &Path) -> (String, String) {
    let summary = std::fs::read(sub.join("summary.json"))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok());
    let field = |k: &str| {
        summary
            .as_ref()
            .and_then(|v| v.get(k))
            .and_then(|v| v.as_str())
            .map(str::to_string)
    };
    let title = field("title").unwrap_or_else(|| {
        std::fs::read_to_string(sub.join("index.html"))
            .ok()
            .and_then(|h| {
                let a = h.find("<title>")? + "<title>".len();
                let b = a + h[a..].find("</title>")?;
                Some(h[a..b].to_string())
            })
            .unwrap_or_default()
    });
    (title, field("claim").unwrap_or_default())
}

/// Writes `root/index.html`: every `root/<name>/index.html`, by name, with
/// its title and claim, and a link to `docs/figures.md` beside `root` if
/// there is one. Titles read from pages are kept as they are (already HTML).
pub fn write_index(root: &Path) -> Result<(), String> {
    let mut pages: Vec<String> = std::fs::read_dir(root)
        .map_err(|e| format!("cannot list {}: {e}", root.display()))?
        .filter_map(Result::ok)
        .filter(|e| e.path().join("index.html").is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    pages.sort();
    let mut h = String::from(
        "<!doctype html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>nonholo results</title>\n\
         <style>body{font-family:sans-serif;max-width:1200px;margin:auto;padding:1em}\
         table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:4px 8px;text-align:left;vertical-align:top}</style>\
         </head><body>\n<h1>nonholo results</h1>\n",
    );
    let figures = root.parent().map(|r| r.join("docs/figures.md"));
    if let Some(f) = figures.filter(|f| f.is_file()) {
        let _ = writeln!(
            h,
            "<p>Every figure with the claim it tests: <a href=\"{}\">docs/figures.md</a>.</p>",
            escape(&super::cli::relative(root, &f))
        );
    }
    let _ = writeln!(
        h,
        "<table><tr><th>result</th><th>title</th><th>claim</th></tr>"
    );
    for name in &pages {
        let (title, claim) = describe(&root.join(name));
        let from_summary = root.join(name).join("summary.json").is_file();
        let _ = writeln!(
            h,
            "<tr><td><a href=\"{0}/index.html\">{0}</a></td><td>{1}</td><td>{2}</td></tr>",
            escape(name),
            if from_summary { escape(&title) } else { title },
            escape(&claim)
        );
    }
    let _ = writeln!(h, "</table></body></html>");
    write(&root.join("index.html"), h.as_bytes())
}
