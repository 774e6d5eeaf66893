//! The experiment runner as a user drives it: results, determinism across
//! thread counts, a sweep killed half-way and resumed, bad files.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{disk_sweep, nonholo};

/// A fresh `<tmp>/experiments/<name>.toml`; results go to `<tmp>/results/<name>`.
fn setup(tag: &str, name: &str, body: &str) -> (PathBuf, PathBuf) {
    let root = common::scratch(&format!("exp-{tag}"));
    let file = root.join(common::experiment(&root, name, body));
    (file, root.join("results").join(name))
}

#[test]
fn results_are_complete_and_legible() {
    let (file, dir) = setup("files", "files", &disk_sweep("files", 5, 20.0));
    let o = nonholo(&["experiment", file.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for f in [
        "runs.csv",
        "pairs.csv",
        "timing.csv",
        "summary.json",
        "config.json",
        "manifest.json",
        "index.html",
    ] {
        assert!(dir.join(f).exists(), "{f} missing");
    }
    let runs = std::fs::read_to_string(dir.join("runs.csv")).unwrap();
    assert_eq!(runs.lines().count(), 1 + 5 * 2);
    assert!(
        runs.lines()
            .next()
            .unwrap()
            .starts_with("point,C.init.lambda1,label,formulation,")
    );
    let manifest: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
    for k in [
        "command",
        "experiment_sha256",
        "git_revision",
        "git_dirty",
        "versions",
        "machine",
        "started",
        "finished",
    ] {
        assert!(manifest.get(k).is_some(), "manifest lacks {k}");
    }
    // Every plot exists as PNG and SVG, and its text is real text.
    for stem in [
        "trajectories",
        "divergence",
        "residual",
        "energy",
        "sweep-end",
    ] {
        let svg = std::fs::read_to_string(dir.join("plots").join(format!("{stem}.svg"))).unwrap();
        assert!(
            svg.contains("<text") && svg.contains("[s]") || svg.contains("[m]"),
            "{stem}: no axis text"
        );
        // Titles name the plotted point plainly (not the TOML line numbers of
        // the error messages).
        assert!(
            !svg.contains("swept at line"),
            "{stem}: title carries line numbers"
        );
        assert!(
            std::fs::metadata(dir.join("plots").join(format!("{stem}.png")))
                .unwrap()
                .len()
                > 10_000
        );
    }
    let html = std::fs::read_to_string(dir.join("index.html")).unwrap();
    assert!(
        html.contains("plots/sweep-end.png")
            && html.contains("<table>")
            && html.contains("figcaption")
    );
    // Redrawing from stored results needs no run.
    let o = nonholo(&["plot", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

#[test]
fn thread_count_does_not_change_results() {
    let (file, dir) = setup("det", "det", &disk_sweep("det", 8, 20.0));
    let f = file.to_str().unwrap();
    let read = |p: &Path| std::fs::read(p).unwrap();
    assert!(
        nonholo(&["experiment", f, "--threads", "1", "--force", "--quiet"])
            .status
            .success()
    );
    let (runs1, pairs1) = (read(&dir.join("runs.csv")), read(&dir.join("pairs.csv")));
    let cores = std::thread::available_parallelism()
        .map(|n| n.get())
        .unwrap_or(2)
        .max(2)
        .to_string();
    assert!(
        nonholo(&["experiment", f, "--threads", &cores, "--force", "--quiet"])
            .status
            .success()
    );
    assert_eq!(
        runs1,
        read(&dir.join("runs.csv")),
        "runs.csv differs between 1 and {cores} threads"
    );
    assert_eq!(pairs1, read(&dir.join("pairs.csv")));
}

/// A sweep killed half-way and started again finishes with every point
/// exactly once, stored points reused, nothing corrupt, no temporary left.
#[test]
fn killed_sweep_resumes() {
    let n = 40;
    // ~50 ms per point on one thread: long enough to kill half-way.
    let (file, dir) = setup("kill", "kill", &disk_sweep("kill", n, 300.0));
    let f = file.to_str().unwrap().to_string();
    let mut child = Command::new(common::bin())
        .args(["experiment", &f, "--threads", "1", "--quiet"])
        .spawn()
        .unwrap();
    let points = dir.join("points");
    let count = || {
        std::fs::read_dir(&points)
            .map(|d| {
                d.flatten()
                    .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
                    .count()
            })
            .unwrap_or(0)
    };
    let start = std::time::Instant::now();
    while count() < 3 && start.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let done_before = count();
    assert!(
        done_before >= 3 && done_before < n,
        "killed after {done_before} of {n} points: make the sweep longer"
    );
    let o = nonholo(&["experiment", &f, "--threads", "2"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains(&format!("{n} points ({done_before} reused)")) || err.contains("reused"),
        "{err}"
    );
    assert_eq!(count(), n);
    let runs = std::fs::read_to_string(dir.join("runs.csv")).unwrap();
    let mut seen: Vec<(String, String)> = runs
        .lines()
        .skip(1)
        .map(|l| {
            let c: Vec<&str> = l.split(',').collect();
            (c[0].to_string(), c[2].to_string())
        })
        .collect();
    assert_eq!(seen.len(), 2 * n);
    seen.sort();
    seen.dedup();
    assert_eq!(
        seen.len(),
        2 * n,
        "a (point, formulation) row appears twice"
    );
    for d in [
        dir.clone(),
        points.clone(),
        dir.join("trajectories"),
        dir.join("plots"),
    ] {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            assert!(
                !e.file_name().to_string_lossy().ends_with(".tmp"),
                "temporary left: {:?}",
                e.path()
            );
        }
    }
    for e in std::fs::read_dir(&points).unwrap().flatten() {
        let v: serde_json::Value =
            serde_json::from_slice(&std::fs::read(e.path()).unwrap()).unwrap();
        assert_eq!(v["schema"], "nonholo.point/1");
    }
}

fn refused(tag: &str, body: &str, needles: &[&str]) {
    let (file, _) = setup(tag, tag, body);
    let o = nonholo(&["experiment", file.to_str().unwrap(), "--quiet"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{tag}: {err}");
    for n in needles {
        assert!(err.contains(n), "{tag}: `{n}` not in {err}");
    }
}

#[test]
fn bad_experiment_files_name_key_and_line() {
    let good = disk_sweep("bad", 2, 20.0);
    refused(
        "unknown-key",
        &good.replace("[time]\n", "[time]\nt_start = 0\n"),
        &["unknown field `t_start`", "line"],
    );
    refused(
        "wrong-type",
        &good.replace("t_end = 20.0", "t_end = \"long\""),
        &["t_end", "line 12"],
    );
    refused(
        "empty-sweep",
        &good.replace(
            r#""C.init.lambda1" = [-2.000, 0.000]"#,
            r#""C.init.lambda1" = []"#,
        ),
        &["sweep.values.C.init.lambda1", "empty list"],
    );
    refused(
        "unknown-formulation",
        &good.replace("formulation = \"vakonomic\"", "formulation = \"lagrange\""),
        &[
            ":23: `formulation.formulation`",
            "unknown formulation `lagrange`",
        ],
    );
    refused(
        "unknown-scene",
        &good.replace("scene = \"rolling-disk\"", "scene = \"disc\""),
        &[
            ":5: `experiment.scene`",
            "unknown scene `disc`",
            "rolling-disk",
        ],
    );
    refused(
        "out-of-range",
        &good.replace("[init]", "[params]\nR = -1\n\n[init]"),
        &["`R` = -1", "(0, inf)"],
    );
    refused(
        "random-range-overflows",
        &good.replace(
            "mode = \"grid\"\nvalues = { \"C.init.lambda1\" = [-2.000, 0.000] }",
            "mode = \"random\"\nsamples = 2\nseed = 1\nranges = { \"C.init.lambda1\" = [-1e308, 1e308] }",
        ),
        &["sweep.ranges.C.init.lambda1", "finite width"],
    );
    refused(
        "step-beyond-budget",
        &good.replace(
            "label = \"B\"\nformulation = \"chetaev\"\nrtol = 1e-12\natol = 1e-12",
            "label = \"B\"\nformulation = \"chetaev\"\nintegrator = \"rk4\"\nstep = 1e-9",
        ),
        &["B: fixed_step = 1e-9", "more than the step budget"],
    );
    refused(
        "hermite-on-an-implicit-form",
        &good.replace(
            "label = \"B\"\nformulation = \"chetaev\"\nrtol = 1e-12\natol = 1e-12",
            "label = \"B\"\nformulation = \"chetaev\"\nintegrator = \"radau5\"\nradau_dense = \"hermite\"\noptions = { form = \"dae\" }",
        ),
        &["B: radau_dense = hermite", "implicit form"],
    );
    refused(
        "bad-sweep-name",
        &good.replace("\"C.init.lambda1\"", "\"D.init.lambda1\""),
        &["cannot address `D.init.lambda1`", "labels: B, C"],
    );
    refused(
        "no-formulation",
        "[experiment]\nname = \"x\"\ntitle = \"t\"\nclaim = \"c\"\nscene = \"pendulum\"\n[time]\nt_end = 1\noutput_every = 0.1\n",
        &["no [[formulation]]"],
    );
}

/// One colour per formulation in every figure of an experiment, whatever
/// the order of its lines: C listed before B is still green and B blue, so
/// vermillion (the second colour by position, A's colour by formulation)
/// appears in none of the figures. (Pairs and sweep curves take the colour
/// of the line compared with the reference, here B.)
#[test]
fn figures_colour_lines_by_formulation() {
    let body = r#"[experiment]
name = "colours"
title = "colours"
claim = "none"
scene = "rolling-disk"

[init]
omega_theta = 0.5
omega_psi = 1.0

[time]
t_end = 1.0
output_every = 0.01

[[formulation]]
label = "C"
formulation = "vakonomic"

[[formulation]]
label = "B"
formulation = "chetaev"

[sweep]
mode = "grid"
values = { "C.init.lambda2" = [-0.5, 0.0, 0.5] }
"#;
    let (file, dir) = setup("colours", "colours", body);
    let o = nonholo(&["experiment", file.to_str().unwrap(), "--quiet"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for plot in [
        "trajectories",
        "residual",
        "energy",
        "divergence",
        "sweep-end",
    ] {
        let svg = std::fs::read_to_string(dir.join("plots").join(format!("{plot}.svg")))
            .unwrap()
            .to_uppercase();
        assert!(!svg.contains("#D55E00"), "{plot}: a line in A's colour");
        assert!(svg.contains("#0072B2"), "{plot}: B not blue");
        if ["trajectories", "residual", "energy"].contains(&plot) {
            assert!(svg.contains("#009E73"), "{plot}: C not green");
        }
    }
}

/// A sweep split into shards (`--shard I/N`, each into its own directory)
/// and merged (`nonholo merge`) gives the results of a single run: its
/// tables byte for byte (wall times, in timing.csv, aside), and a merge
/// with a shard missing names the points and the shard that computes them.
#[test]
fn shards_merge_into_the_single_run() {
    let (file, single) = setup("shards", "shards", &disk_sweep("shards", 7, 5.0));
    let f = file.to_str().unwrap();
    let o = nonholo(&["experiment", f, "--quiet", "--threads", "2"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let root = single.parent().unwrap().to_path_buf();
    let mut shards = Vec::new();
    for i in 1..=3 {
        let o = nonholo(&["experiment", f, "--quiet", "--shard", &format!("{i}/3")]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let dir = root.join(format!("shards.shard-{i}-of-3"));
        assert!(dir.join("shard.json").is_file());
        assert!(!dir.join("runs.csv").exists(), "a shard writes no tables");
        shards.push(dir.to_str().unwrap().to_string());
    }
    let merged = root.join("merged");
    let mut args = vec!["merge", f, "--quiet", "--out", merged.to_str().unwrap()];
    args.extend(shards.iter().map(String::as_str));
    let o = nonholo(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    for table in ["runs.csv", "pairs.csv", "summary.json", "config.json"] {
        assert_eq!(
            std::fs::read(single.join(table)).unwrap(),
            std::fs::read(merged.join(table)).unwrap(),
            "{table} differs"
        );
    }
    // A shard missing: exit 2, the points named with the command that
    // computes them.
    let partial = root.join("partial");
    let o = nonholo(&[
        "merge",
        f,
        "--quiet",
        "--out",
        partial.to_str().unwrap(),
        &shards[0],
        &shards[2],
    ]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("2 of 7 points are stored in none of the shard directories (points 1, 4)")
            && err.contains("--shard 2/3"),
        "{err}"
    );
    assert!(!partial.exists(), "a refused merge writes nothing");
    // A shard directory is the shard's: no full results, no merge into it,
    // and not given twice.
    let o = nonholo(&["experiment", f, "--quiet", "--out", &shards[0]]);
    assert_eq!(o.status.code(), Some(2));
    // Nor does a shard write into a directory of full results.
    let o = nonholo(&[
        "experiment",
        f,
        "--quiet",
        "--shard",
        "1/3",
        "--out",
        single.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("holds the full results"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(!single.join("shard.json").exists());
    let o = nonholo(&["merge", f, "--quiet", "--out", &shards[0], &shards[1]]);
    assert_eq!(o.status.code(), Some(2));
    let o = nonholo(&[
        "merge",
        f,
        "--quiet",
        "--out",
        merged.to_str().unwrap(),
        &shards[0],
        &shards[0],
    ]);
    assert_eq!(
        o.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // Bad shard values are refused before anything runs.
    for bad in ["0/3", "4/3", "x"] {
        let o = nonholo(&["experiment", f, "--quiet", "--shard", bad]);
        assert_eq!(o.status.code(), Some(2), "--shard {bad}");
    }
}

/// `nonholo compare`: the same experiment run twice (other thread counts,
/// so other wall times) holds the same results, exit 0; a number moved in
/// one copy is reported with its table, row, column and both values, exit
/// 6; a directory that does not exist is refused, exit 2.
#[test]
fn compare_finds_equal_runs_equal_and_names_a_moved_number() {
    let (file, dir) = setup("cmp", "cmp", &disk_sweep("cmp", 4, 5.0));
    let f = file.to_str().unwrap();
    let other = dir.with_file_name("cmp-again");
    let o = other.to_str().unwrap();
    for (out, threads) in [(dir.to_str().unwrap(), "1"), (o, "2")] {
        let run = nonholo(&[
            "experiment",
            f,
            "--out",
            out,
            "--threads",
            threads,
            "--quiet",
        ]);
        assert!(run.status.success(), "{}", common::stderr(&run));
    }
    let d = dir.to_str().unwrap();
    let same = nonholo(&["compare", d, o]);
    let text = String::from_utf8_lossy(&same.stdout).into_owned();
    assert_eq!(same.status.code(), Some(0), "{text}");
    assert!(
        text.starts_with("equal: 1 experiment(s), 2 table(s)"),
        "{text}"
    );

    // One cell of the copy's runs.csv moved: C's distance at point 0.
    let runs = other.join("runs.csv");
    let mut reader = csv::Reader::from_path(&runs).unwrap();
    let header = reader.headers().unwrap().clone();
    let mut records: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    let col = header.iter().position(|h| h == "div_xy_end").unwrap();
    let before = records[1][col].to_string();
    let mut moved: Vec<&str> = records[1].iter().collect();
    moved[col] = "0.125";
    records[1] = csv::StringRecord::from(moved);
    let mut writer = csv::Writer::from_path(&runs).unwrap();
    writer.write_record(&header).unwrap();
    for r in &records {
        writer.write_record(r).unwrap();
    }
    writer.flush().unwrap();
    let moved = nonholo(&["compare", d, o]);
    let text = String::from_utf8_lossy(&moved.stdout).into_owned();
    assert_eq!(moved.status.code(), Some(6), "{text}");
    assert!(
        text.contains(&format!(
            "runs.csv row 2 (point 0, label C), div_xy_end: {before} | 0.125"
        )),
        "{text}"
    );
    assert!(
        text.lines().last().unwrap().starts_with("different:"),
        "{text}"
    );

    let missing = nonholo(&["compare", d, "/nonexistent/results"]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(common::stderr(&missing).contains("not a directory"));
    // A negative tolerance is refused for what it is, not as an argument.
    let neg = nonholo(&["compare", d, o, "--rtol", "-1"]);
    assert_eq!(neg.status.code(), Some(2));
    assert!(
        common::stderr(&neg).contains("--rtol: -1 must be at least 0"),
        "{}",
        common::stderr(&neg)
    );

    // Another experiment's results: nothing in common, refused (exit 2),
    // as two results directories with no experiment in common are.
    let (file2, dir2) = setup("cmp2", "cmp2", &disk_sweep("cmp2", 2, 1.0));
    let run = nonholo(&["experiment", file2.to_str().unwrap(), "--quiet"]);
    assert!(run.status.success(), "{}", common::stderr(&run));
    let foreign = nonholo(&["compare", d, dir2.to_str().unwrap()]);
    assert_eq!(
        foreign.status.code(),
        Some(2),
        "{}",
        common::stderr(&foreign)
    );
    assert!(
        common::stderr(&foreign).contains("nothing in common"),
        "{}",
        common::stderr(&foreign)
    );
    let roots = [dir.parent().unwrap(), dir2.parent().unwrap()].map(|p| p.to_str().unwrap());
    let disjoint = nonholo(&["compare", roots[0], roots[1]]);
    assert_eq!(
        disjoint.status.code(),
        Some(2),
        "{}",
        common::stderr(&disjoint)
    );
    assert!(common::stderr(&disjoint).contains("no experiment in common"));
}
