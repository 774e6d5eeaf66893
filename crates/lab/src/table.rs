//! Result tables: typed records (`#[derive(Serialize)]`) written as CSV by
//! the `csv` crate, and the same tables as HTML.
//!
//! The columns of a record type are its field names in order, a nested
//! struct contributing its own fields in its place ([`columns`]), so a
//! header cannot disagree with its rows. An experiment's tables lead every
//! row with the point's index and swept values:
//! `point, <axis>…, <fields of the record>…` ([`Table::per_point`]). Tables
//! of sampled states (trajectories, references, `nonholo simulate --out
//! FILE.csv`) have as many columns as the scene has coordinates; their
//! header is built by [`state_header`].
//!
//! Numbers are written as the tables have always had them, which scripts
//! rely on: a float as Rust's `Display` prints it, the shortest digits that
//! round-trip in fixed notation (`0.00000000001`, never `1e-11`), through
//! [`plain`], [`plain_opt`] and [`plain_seq`] (the csv crate's own float
//! format is exponential) — for magnitudes in `[1e-30, 1e21)` and zero;
//! outside that range the shortest round-trip digits in exponent notation
//! (`1e160`, `5e-324`), not hundreds of digits. A value that is not finite
//! is never written: [`Plain`] refuses it, and the row with it (NaN or an
//! infinity in a result file would be read as a number). Integers are
//! written as digits; `None` as an empty field.

use std::path::Path;

use serde::{Serialize, Serializer};
use serde_json::Value as Json;

use crate::record::write_atomic;

/// A float written as `Display` prints it (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plain(pub f64);

/// Smallest magnitude written in fixed notation.
const FIXED_MIN: f64 = 1e-30;
/// Magnitudes from here on are written in exponent notation.
const FIXED_MAX: f64 = 1e21;

impl Plain {
    /// The text of a finite value (see the module documentation).
    pub fn text(v: f64) -> String {
        let a = v.abs();
        if v == 0.0 || (FIXED_MIN..FIXED_MAX).contains(&a) {
            format!("{v}")
        } else {
            format!("{v:e}")
        }
    }
}

impl Serialize for Plain {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if !self.0.is_finite() {
            return Err(serde::ser::Error::custom(format!(
                "refusing to write a value that is not finite ({})",
                self.0
            )));
        }
        s.collect_str(&Plain::text(self.0))
    }
}

/// A CSV file with a header: its column names and records; an error names
/// the file (a record with another number of fields than the header is
/// one).
pub fn read_csv(path: &Path) -> Result<(Vec<String>, Vec<csv::StringRecord>), String> {
    let mut reader =
        csv::Reader::from_path(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let header = reader
        .headers()
        .map_err(|e| format!("{}: {e}", path.display()))?
        .iter()
        .map(String::from)
        .collect();
    let records = reader
        .records()
        .collect::<Result<Vec<_>, _>>()
        .map_err(|e| format!("{}: {e}", path.display()))?;
    Ok((header, records))
}

/// `serialize_with` for an `f64` field: [`Plain`].
pub fn plain<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    Plain(*v).serialize(s)
}

/// `serialize_with` for an `Option<f64>` field: [`Plain`], or an empty field.
pub fn plain_opt<S: Serializer>(v: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
    v.map(Plain).serialize(s)
}

/// `serialize_with` for a sequence of floats: one [`Plain`] field each (a
/// variable number of columns: the table's header must be written by hand,
/// see [`Table::new`]).
pub fn plain_seq<S: Serializer, V: AsRef<[f64]>>(v: &V, s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(v.as_ref().iter().map(|x| Plain(*x)))
}

/// The column names of record type `R`: its field names in order, a nested
/// struct's fields in its place. `R` has no sequence and no optional
/// struct (their width would depend on the value).
pub fn columns<R: Serialize + Default>() -> Result<Vec<String>, String> {
    fn leaves(v: &Json, out: &mut Vec<String>) -> Result<(), String> {
        let Json::Object(fields) = v else {
            return Err("a table record must be a struct".into());
        };
        for (name, value) in fields {
            match value {
                Json::Object(_) => leaves(value, out)?,
                Json::Array(_) => {
                    return Err(format!(
                        "table record field `{name}` is a sequence: its width is not fixed"
                    ));
                }
                _ => out.push(name.clone()),
            }
        }
        Ok(())
    }
    let value = serde_json::to_value(R::default()).map_err(|e| e.to_string())?;
    let mut out = Vec::new();
    leaves(&value, &mut out)?;
    Ok(out)
}

/// A CSV table being built in memory.
pub struct Table {
    w: csv::Writer<Vec<u8>>,
    header: Vec<String>,
    rows: usize,
}

impl Table {
    /// A table with the columns `header`; rows are added with [`Table::push`].
    pub fn new<I, T>(header: I) -> Result<Table, String>
    where
        I: IntoIterator<Item = T>,
        T: AsRef<[u8]>,
    {
        // Headers are written here, not derived by csv from the first row:
        // a row starts with the point and its swept values, which are not
        // struct fields.
        let header: Vec<String> = header
            .into_iter()
            .map(|h| String::from_utf8_lossy(h.as_ref()).into_owned())
            .collect();
        let mut w = csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(Vec::new());
        w.write_record(&header).map_err(|e| e.to_string())?;
        Ok(Table { w, header, rows: 0 })
    }

    /// A table whose rows are records `R` at sweep points:
    /// `point, <axis>…, <columns of R>…`; rows are added with [`Table::at_point`].
    pub fn per_point<'a, R: Serialize + Default>(
        axes: impl IntoIterator<Item = &'a str>,
    ) -> Result<Table, String> {
        let header = ["point".to_string()]
            .into_iter()
            .chain(axes.into_iter().map(String::from))
            .chain(columns::<R>()?);
        Table::new(header)
    }

    /// Appends one row: the fields of `row` in order. A value that is not
    /// finite is refused, naming the row (the table is then not to be
    /// written).
    pub fn push(&mut self, row: &impl Serialize) -> Result<(), String> {
        self.w
            .serialize(row)
            .map_err(|e| format!("row {} of the table: {e}", self.rows + 1))?;
        self.rows += 1;
        Ok(())
    }

    /// Appends a sampled state, refusing (with the time and the column) a
    /// value that is not finite.
    pub fn push_state(&mut self, row: &StateRow) -> Result<(), String> {
        let values = std::iter::once(row.t)
            .chain(row.q.iter().copied())
            .chain(row.q_dot.iter().copied())
            .chain(row.more.iter().flat_map(|m| m.iter().copied()));
        for (v, name) in values.zip(&self.header) {
            if !v.is_finite() {
                return Err(format!(
                    "refusing to write a value that is not finite: `{name}` = {v} at t = {}",
                    row.t
                ));
            }
        }
        self.push(row)
    }

    /// Appends `record` at the point `index` with swept `values`.
    pub fn at_point(
        &mut self,
        index: usize,
        values: &[String],
        record: &impl Serialize,
    ) -> Result<(), String> {
        self.push(&(index, values, record))
    }

    /// The CSV text.
    pub fn into_bytes(self) -> Result<Vec<u8>, String> {
        self.w.into_inner().map_err(|e| e.to_string())
    }

    /// Writes the table to `path` (atomically).
    pub fn write(self, path: &Path) -> Result<(), String> {
        write_atomic(path, &self.into_bytes()?)
            .map_err(|e| format!("cannot write {}: {e}", path.display()))
    }
}

/// One sampled state: `t`, `q…`, `q̇…`, then the values of every slice of
/// `more` (multipliers, residual, energy, …). Its header: [`state_header`].
#[derive(Serialize)]
pub struct StateRow<'a> {
    #[serde(serialize_with = "plain")]
    pub t: f64,
    #[serde(serialize_with = "plain_seq")]
    pub q: &'a [f64],
    #[serde(serialize_with = "plain_seq")]
    pub q_dot: &'a [f64],
    #[serde(serialize_with = "plain_seqs")]
    pub more: &'a [&'a [f64]],
}

fn plain_seqs<S: Serializer>(v: &&[&[f64]], s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(v.iter().flat_map(|x| x.iter()).map(|x| Plain(*x)))
}

/// The header of a table of sampled states: `t`, the coordinates, their
/// velocities `<q>_dot`, then `more`.
pub fn state_header<'a>(
    coordinates: impl Iterator<Item = &'a str> + Clone,
    more: impl IntoIterator<Item = String>,
) -> Vec<String> {
    ["t".to_string()]
        .into_iter()
        .chain(coordinates.clone().map(String::from))
        .chain(coordinates.map(|c| format!("{c}_dot")))
        .chain(more)
        .collect()
}

/// `s` with the characters that mean something in HTML escaped.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// An HTML table: the first row as header cells, the others as data cells;
/// cell text is escaped.
pub fn html<R, C>(rows: impl IntoIterator<Item = R>) -> String
where
    R: IntoIterator<Item = C>,
    C: AsRef<str>,
{
    let mut h = String::from("<table>\n");
    for (i, row) in rows.into_iter().enumerate() {
        let tag = if i == 0 { "th" } else { "td" };
        h.push_str("<tr>");
        for c in row {
            let c = c.as_ref();
            let shown = if i == 0 { c.to_string() } else { readable(c) };
            h.push_str(&format!("<{tag}>{}</{tag}>", escape(&shown)));
        }
        h.push_str("</tr>\n");
    }
    h.push_str("</table>\n");
    h
}

/// A table cell for reading: a number that is not an integer to four
/// significant digits (`2.265e-7`, `0.9231`), everything else as written.
/// The files keep every digit; pages show these.
pub fn readable(cell: &str) -> String {
    let integer = !cell.is_empty()
        && cell
            .trim_start_matches('-')
            .bytes()
            .all(|b| b.is_ascii_digit());
    match cell.parse::<f64>() {
        Ok(x) if x.is_finite() && !integer && x != 0.0 => {
            let exponent = x.abs().log10().floor() as i32;
            if (-3..5).contains(&exponent) {
                let decimals = (3 - exponent).max(0) as usize;
                let fixed = format!("{x:.decimals$}");
                if fixed.contains('.') {
                    fixed
                        .trim_end_matches('0')
                        .trim_end_matches('.')
                        .to_string()
                } else {
                    fixed
                }
            } else {
                let sci = format!("{x:.3e}");
                // 1.500e-7 → 1.5e-7
                match sci.split_once('e') {
                    Some((m, e)) => {
                        let m = if m.contains('.') {
                            m.trim_end_matches('0').trim_end_matches('.')
                        } else {
                            m
                        };
                        format!("{m}e{e}")
                    }
                    None => sci,
                }
            }
        }
        _ => cell.to_string(),
    }
}

/// The CSV file `path` as an HTML table (an empty table if it cannot be read).
pub fn html_from_csv(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let records = csv::ReaderBuilder::new()
        .has_headers(false)
        .from_reader(text.as_bytes())
        .into_records()
        .flatten();
    let rows: Vec<Vec<String>> = records
        .map(|r| r.iter().map(String::from).collect())
        .collect();
    let shown = rows.len().min(MAX_HTML_ROWS + 1);
    let mut out = html(rows[..shown].iter().cloned());
    if rows.len() > shown {
        let name = path
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into_owned());
        out.push_str(&format!(
            "<p>The first {MAX_HTML_ROWS} of {} rows; all of them in <a href=\"{name}\">{name}</a>.</p>\n",
            rows.len() - 1
        ));
    }
    out
}

/// The most rows of a CSV table a results page shows (the header aside):
/// a sweep of thousands of points keeps a page of a few hundred kilobytes,
/// its full table in the CSV file the page links to.
pub const MAX_HTML_ROWS: usize = 500;

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Default, Serialize)]
    struct Inner {
        steps: usize,
        #[serde(serialize_with = "plain")]
        h: f64,
    }

    #[derive(Default, Serialize)]
    struct Record<'a> {
        label: &'a str,
        #[serde(serialize_with = "plain")]
        rtol: f64,
        inner: Inner,
        #[serde(serialize_with = "plain_opt")]
        t_last: Option<f64>,
        error: Option<&'a str>,
    }

    /// A long CSV shows its first rows and links to the file.
    #[test]
    fn long_tables_are_cut_on_pages() {
        let dir = std::env::temp_dir().join(format!("nonholo-table-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("runs.csv");
        let mut text = String::from("point,label\n");
        for i in 0..(MAX_HTML_ROWS + 7) {
            text.push_str(&format!("{i},B\n"));
        }
        std::fs::write(&path, &text).unwrap();
        let page = html_from_csv(&path);
        assert_eq!(page.matches("<tr>").count(), MAX_HTML_ROWS + 1);
        assert!(page.contains(&format!(
            "The first {MAX_HTML_ROWS} of {} rows",
            MAX_HTML_ROWS + 7
        )));
        assert!(page.contains("<a href=\"runs.csv\">runs.csv</a>"));
        std::fs::write(&path, "point,label\n0,B\n").unwrap();
        assert!(!html_from_csv(&path).contains("The first"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn readable_cells_have_four_significant_digits() {
        for (cell, shown) in [
            ("0.00000000001", "1e-11"),
            ("0.0000002265359926312271", "2.265e-7"),
            ("0.9230505824350157", "0.9231"),
            ("2.245", "2.245"),
            ("12.5", "12.5"),
            ("423.97665881089955", "424"),
            ("125", "125"),
            ("1000000", "1000000"),
            ("123456.7", "1.235e5"),
            ("0", "0"),
            ("-0.000012345", "-1.234e-5"),
            ("completed", "completed"),
            ("", ""),
        ] {
            assert_eq!(readable(cell), shown, "{cell}");
        }
    }

    #[test]
    fn columns_follow_the_fields_with_nested_structs_in_place() {
        assert_eq!(
            columns::<Record>().unwrap(),
            ["label", "rtol", "steps", "h", "t_last", "error"]
        );
    }

    /// Floats as `Display` prints them (fixed notation, shortest digits),
    /// `None` empty, text quoted only where CSV needs it: the rows the
    /// positional `Vec<String>` code wrote.
    #[test]
    fn rows_have_the_text_of_display() {
        let mut t = Table::per_point::<Record>(["param.alpha"]).unwrap();
        let values = vec!["0.3".to_string()];
        let r = Record {
            label: "B",
            rtol: 1e-11,
            inner: Inner { steps: 12, h: 1e20 },
            t_last: Some(0.1 + 0.2),
            error: Some("stopped, at t = 1"),
        };
        t.at_point(7, &values, &r).unwrap();
        t.at_point(8, &values, &Record::default()).unwrap();
        let text = String::from_utf8(t.into_bytes().unwrap()).unwrap();
        let by_hand = [
            "point,param.alpha,label,rtol,steps,h,t_last,error".to_string(),
            [
                7.to_string(),
                "0.3".into(),
                "B".into(),
                1e-11.to_string(),
                12.to_string(),
                1e20.to_string(),
                (0.1 + 0.2).to_string(),
                "\"stopped, at t = 1\"".into(),
            ]
            .join(","),
            "8,0.3,,0,0,0,,".to_string(),
        ];
        assert_eq!(text, by_hand.join("\n") + "\n");
        assert!(text.contains(",0.00000000001,12,100000000000000000000,0.30000000000000004,"));
    }

    /// Outside `[1e-30, 1e21)` a value is written in exponent notation with
    /// the digits that round-trip, not as hundreds of digits.
    #[test]
    fn extreme_magnitudes_are_written_short_and_exact() {
        for v in [1e21, 1e160, -9.800665778412416e159, 1e-31, 5e-324, f64::MAX] {
            let s = Plain::text(v);
            assert!(s.len() < 30, "{s}");
            assert_eq!(s.parse::<f64>().unwrap().to_bits(), v.to_bits(), "{s}");
        }
        assert_eq!(Plain::text(1e160), "1e160");
        assert_eq!(
            Plain::text(2.710505431213761e-20),
            "0.00000000000000000002710505431213761"
        );
        assert_eq!(Plain::text(0.0), "0");
    }

    /// NaN and infinities are refused with the row (and for states, the
    /// column and time): no result file holds one.
    #[test]
    fn non_finite_values_are_refused() {
        let mut t = Table::per_point::<Record>(["param.alpha"]).unwrap();
        let nan = Record {
            rtol: f64::NAN,
            ..Record::default()
        };
        let e = t.at_point(8, &["0.3".into()], &nan).unwrap_err();
        assert!(e.contains("row 1") && e.contains("not finite"), "{e}");
        let mut t = Table::new(state_header(
            ["x", "y"].into_iter(),
            ["residual", "energy"].map(String::from),
        ))
        .unwrap();
        let e = t
            .push_state(&StateRow {
                t: 0.5,
                q: &[1.0, 2.0],
                q_dot: &[0.0, 1e-3],
                more: &[&[4.0, f64::INFINITY]],
            })
            .unwrap_err();
        assert!(e.contains("`energy` = inf at t = 0.5"), "{e}");
    }

    #[test]
    fn states_give_one_field_per_value() {
        let mut t = Table::new(state_header(
            ["x", "y"].into_iter(),
            ["lambda", "residual", "energy"].map(String::from),
        ))
        .unwrap();
        t.push_state(&StateRow {
            t: 0.5,
            q: &[1.0, -2e-7],
            q_dot: &[0.0, 1e-3],
            more: &[&[], &[4.0], &[5.5, 1e160]],
        })
        .unwrap();
        let text = String::from_utf8(t.into_bytes().unwrap()).unwrap();
        assert_eq!(
            text,
            "t,x,y,x_dot,y_dot,lambda,residual,energy\n0.5,1,-0.0000002,0,0.001,4,5.5,1e160\n"
        );
    }

    #[test]
    fn html_tables_escape_their_cells() {
        let h = html([vec!["a", "b<c"], vec!["1", "x & y"]]);
        assert_eq!(
            h,
            "<table>\n<tr><th>a</th><th>b&lt;c</th></tr>\n<tr><td>1</td><td>x &amp; y</td></tr>\n</table>\n"
        );
    }
}
