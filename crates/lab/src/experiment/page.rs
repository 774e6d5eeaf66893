//! `index.html`: the page of an experiment (either kind): title, the
//! figure that stands for it (the one docs/figures.md cites), the claim,
//! how to reproduce it (command, experiment file, the figures page),
//! description, links to the result files, tables (numbers to four
//! significant digits; the files keep every digit), and every other figure
//! with its caption.

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
            let _ = writeln!(
                h,
                "<figure><img src=\"{rel}\" alt=\"{stem}\"><figcaption>{}</figcaption></figure>",
                escape(&(self.caption)(&stem))
            );
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

    /// Writes the page to `dir/index.html`.
    pub fn write(&self, dir: &Path) -> Result<(), String> {
        write(&dir.join("index.html"), self.html(dir).as_bytes())
    }
}
