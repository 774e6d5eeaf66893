//! Issue 10, "no hang, no panic, no lost sweep, results identical however
//! they were produced": one test per finding, with the issue's command
//! lines where they can be run as given. (The fuzz test over the command
//! line and experiment files is `fuzz.rs`.)

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;

fn code(o: &std::process::Output) -> Option<i32> {
    o.status.code()
}

fn assert_no_panic(o: &std::process::Output) {
    let e = stderr(o);
    assert_ne!(code(o), Some(101), "{e}");
    assert!(!e.contains("panicked"), "{e}");
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// The files that must not depend on how a sweep was produced.
const COMPARABLE: [&str; 3] = ["runs.csv", "pairs.csv", "summary.json"];

fn comparable(dir: &Path) -> Vec<Vec<u8>> {
    COMPARABLE.iter().map(|f| read(&dir.join(f))).collect()
}

// Item 2: a closed stderr neither panics nor loses the sweep.
#[test]
fn a_closed_stderr_neither_panics_nor_loses_the_sweep() {
    let root = scratch("rel-stderr");
    let file = experiment(&root, "s", &disk_sweep("s", 30, 5.0));
    let o = shell(&root, &format!("nonholo experiment {file} 2>&1 | head -1"));
    assert_no_panic(&o);
    assert_eq!(code(&o), Some(0), "{}", stderr(&o));
    for f in COMPARABLE {
        assert!(root.join("results/s").join(f).exists(), "{f} missing");
    }
    let o = shell(
        &root,
        "nonholo simulate --scene sleigh-incline --param a=bogus 2>&1 | true",
    );
    assert_no_panic(&o);
    assert_eq!(code(&o), Some(2));
}

// Item 3: points reloaded from points/*.json give the tables a fresh run
// gives, to the last digit.
#[test]
fn resumed_results_equal_fresh_ones() {
    let root = scratch("rel-resume");
    let file = experiment(&root, "s", &sleigh_sweep("s"));
    let dir = root.join("results/s");
    let o = nonholo_in(&root, &["experiment", &file, "--force", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let fresh = comparable(&dir);
    let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("(9 reused)"), "{}", stderr(&o));
    for (f, (a, b)) in COMPARABLE.iter().zip(fresh.iter().zip(comparable(&dir))) {
        assert!(*a == b, "{f} differs between a fresh and a resumed run");
    }
    // A stored point that lacks a formulation's run (a file cut short or
    // edited) is computed again, not reused with a row missing.
    let path = dir.join("points/3.json");
    let mut v: serde_json::Value = serde_json::from_slice(&read(&path)).unwrap();
    v["formulations"].as_array_mut().unwrap().pop();
    std::fs::write(&path, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
    let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("(8 reused)"), "{}", stderr(&o));
    // Every row is back (its wall time is the new run's).
    let lines = |b: &[u8]| b.iter().filter(|&&c| c == b'\n').count();
    for (f, (a, b)) in COMPARABLE.iter().zip(fresh.iter().zip(comparable(&dir))) {
        assert_eq!(lines(a), lines(&b), "{f}: rows after a cut point ran again");
    }
}

// Trajectories are not committed (.gitignore): a run without --force on a
// fresh clone computes the plotted point again for them, and keeps its
// stored result, wall times included, where the run agrees with it.
#[test]
fn regenerated_trajectories_keep_the_stored_point() {
    let root = scratch("rel-traj");
    let file = experiment(&root, "s", &sleigh_sweep("s"));
    let dir = root.join("results/s");
    let o = nonholo_in(&root, &["experiment", &file, "--force", "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let point = read(&dir.join("points/0.json"));
    let timing = read(&dir.join("timing.csv"));
    let trajectories = dir.join("trajectories");
    let names = |d: &Path| {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    };
    let before = names(&trajectories);
    assert!(before.iter().any(|n| n.starts_with("0-")), "{before:?}");
    std::fs::remove_dir_all(&trajectories).unwrap();
    let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // The plotted point ran again (8 of 9 reused) and wrote its
    // trajectories; its stored file and the timings are the same bytes.
    assert!(stderr(&o).contains("(8 reused)"), "{}", stderr(&o));
    assert_eq!(names(&trajectories), before);
    assert!(
        read(&dir.join("points/0.json")) == point,
        "points/0.json rewritten"
    );
    assert!(
        read(&dir.join("timing.csv")) == timing,
        "timing.csv rewritten"
    );
    // A stored result that disagrees beyond its wall times is replaced.
    let text = String::from_utf8(point.clone()).unwrap();
    let steps = text.find("\"steps\": ").expect("a step count");
    let edited = format!("{}\"steps\": 1{}", &text[..steps], &text[steps + 9..]);
    std::fs::write(dir.join("points/0.json"), &edited).unwrap();
    std::fs::remove_dir_all(&trajectories).unwrap();
    let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let again = String::from_utf8(read(&dir.join("points/0.json"))).unwrap();
    assert_ne!(again, edited, "a stored result that disagrees was kept");
}

// Item 4: a run stopped by its wall-time budget is recorded as such, with
// nothing that depends on the machine in the comparable tables, so they do
// not depend on the thread count (or on the run).
#[test]
fn wall_time_stops_do_not_change_the_tables() {
    let root = scratch("rel-walltime");
    let body = r#"[experiment]
name = "w"
title = "t"
claim = "c"
scene = "sleigh-incline"

[params]
a = 0.4
alpha = 0.3

[init]
phi = 0.2
u = 2
omega = 0.7

[time]
t_end = 5.0
output_every = 0.05

[[formulation]]
label = "B"
formulation = "chetaev"

[[formulation]]
label = "visc-dop853"
formulation = "visc"
integrator = "dop853"
max_wall_time = 0.3
options = { form = "adapted" }

[sweep]
mode = "grid"
values = { "option.k" = [1e7, 1e8] }
"#;
    let file = experiment(&root, "w", body);
    let dir = root.join("results/w");
    let mut tables = Vec::new();
    let mut timings = Vec::new();
    for threads in ["1", "2"] {
        let o = nonholo_in(
            &root,
            &[
                "experiment",
                &file,
                "--threads",
                threads,
                "--force",
                "--quiet",
            ],
        );
        assert_eq!(code(&o), Some(3), "{}", stderr(&o));
        tables.push(comparable(&dir));
        timings.push(String::from_utf8(read(&dir.join("timing.csv"))).unwrap());
    }
    assert!(
        tables[0] == tables[1],
        "tables differ between 1 and 2 threads"
    );
    let runs = String::from_utf8(tables[0][0].clone()).unwrap();
    let stopped: Vec<&str> = runs.lines().filter(|l| l.contains("visc-dop853")).collect();
    assert_eq!(stopped.len(), 2);
    for l in stopped {
        assert!(l.contains("wall-time budget of 0.3 s used up"), "{l}");
        assert!(l.contains(",failed,,,"), "no time reached in runs.csv: {l}");
    }
    // The time reached is kept where machine-dependent values go.
    assert!(timings[0].starts_with("point,label,wall_time_s,wall_time_stop_t\n"));
    assert!(
        timings[0]
            .lines()
            .filter(|l| l.contains("visc-dop853"))
            .all(|l| !l.ends_with(',')),
        "{}",
        timings[0]
    );
}

/// Figure experiments stop their runs on step budgets: their results may
/// not depend on the machine.
#[test]
fn figure_experiments_budget_steps_not_wall_time() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../experiments");
    for e in std::fs::read_dir(&dir).unwrap().flatten() {
        let p = e.path();
        if p.extension().is_none_or(|x| x != "toml") {
            continue;
        }
        let exp = nonholo_lab::experiment::Experiment::load(&p).unwrap();
        if !exp.figure {
            continue;
        }
        for f in &exp.formulations {
            assert_eq!(
                f.settings.max_wall_time,
                None,
                "{}: {} has a wall-time budget",
                p.display(),
                f.label
            );
        }
    }
}

// Item 5: a failed run is an error whatever happens to stdout.
#[test]
fn a_failed_run_fails_even_with_stdout_closed() {
    let root = scratch("rel-stdout");
    let o = shell(
        &root,
        "nonholo simulate --scene appell-hamel --param c=-0.5 --t-end 5 2>err.txt | true",
    );
    assert_eq!(code(&o), Some(1));
    let err = std::fs::read_to_string(root.join("err.txt")).unwrap();
    assert!(err.contains("singular set"), "{err}");
    // A listing that could not be delivered is an output error: stdout is
    // a pipe whose reader is gone before nonholo starts.
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(bin())
        .arg("scenes")
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert_no_panic(&o);
    assert_eq!(code(&o), Some(4), "{}", stderr(&o));
}

// Item 6: sweeps are bounded, and refused at once when too large.
#[test]
fn unbounded_sweeps_are_refused_at_once() {
    let root = scratch("rel-unbounded");
    let head = r#"[experiment]
name = "u"
title = "t"
claim = "c"
scene = "sleigh-incline"

[time]
t_end = 0.1
output_every = 0.05

[[formulation]]
label = "B"
formulation = "chetaev"

"#;
    let values: Vec<String> = (1..60).map(|i| format!("{:?}", 0.01 * i as f64)).collect();
    let v = values.join(", ");
    for (tag, sweep, needle) in [
        (
            "max",
            "[sweep]\nmode = \"random\"\nranges = { \"param.alpha\" = [0.1, 0.5] }\nsamples = 18446744073709551615\n".to_string(),
            ":18: `sweep.samples`",
        ),
        (
            "float",
            "[sweep]\nmode = \"random\"\nranges = { \"param.alpha\" = [0.1, 0.5] }\nsamples = 1e13\n".to_string(),
            "line 18",
        ),
        (
            "grid",
            format!(
                "[sweep]\nmode = \"grid\"\nvalues = {{ \"param.alpha\" = [{v}], \"param.a\" = [{v}], \"init.u\" = [{v}], \"init.omega\" = [{v}] }}\n"
            ),
            ":16: `sweep.values`: 12117361 sweep points",
        ),
    ] {
        let file = experiment(&root, tag, &format!("{head}{sweep}"));
        let started = Instant::now();
        let o = nonholo_in(&root, &["experiment", &file]);
        assert_no_panic(&o);
        assert_eq!(code(&o), Some(2), "{tag}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{tag}: {}", stderr(&o));
        assert!(started.elapsed() < Duration::from_secs(5), "{tag}: slow refusal");
        assert!(!root.join("results").exists(), "{tag}: wrote results");
    }
}

/// Waits until `dir/points` holds at least `n` point files.
fn wait_points(dir: &Path, n: usize, limit: Duration) -> usize {
    let start = Instant::now();
    loop {
        let count = std::fs::read_dir(dir.join("points"))
            .map(|d| {
                d.flatten()
                    .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
                    .count()
            })
            .unwrap_or(0);
        if count >= n || start.elapsed() > limit {
            return count;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
}

// Item 7: a results directory is written by one process at a time; a lock
// left by a dead process does not block.
#[test]
fn one_writer_per_results_directory() {
    let root = scratch("rel-lock");
    let file = experiment(&root, "l", &disk_sweep("l", 40, 300.0));
    let dir = root.join("results/l");
    let mut first = Command::new(bin())
        .args(["experiment", &file, "--threads", "1", "--quiet"])
        .current_dir(&root)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    assert!(wait_points(&dir, 1, Duration::from_secs(60)) >= 1);
    let second = nonholo_in(&root, &["experiment", &file, "--threads", "1", "--quiet"]);
    assert_eq!(code(&second), Some(5), "{}", stderr(&second));
    let e = stderr(&second);
    assert!(
        e.contains("in use by another nonholo process") && e.contains("pid"),
        "{e}"
    );
    // The holder is killed: its lock goes with it.
    first.kill().unwrap();
    first.wait().unwrap();
    let third = nonholo_in(&root, &["experiment", &file, "--threads", "2", "--quiet"]);
    assert!(third.status.success(), "{}", stderr(&third));
    assert!(
        !dir.join(".nonholo.lock").exists(),
        "lock file left after a finished run"
    );
    assert_eq!(
        String::from_utf8(read(&dir.join("runs.csv")))
            .unwrap()
            .lines()
            .count(),
        81
    );
}

// Item 8: output targets are checked before a run; nothing is written where
// it should not be.
#[test]
fn writes_only_where_asked() {
    let root = scratch("rel-writes");
    let quick = [
        "simulate",
        "--scene",
        "sleigh-incline",
        "--t-end",
        "1",
        "--out",
    ];
    let with_out = |out: &str| {
        let mut a: Vec<&str> = quick.to_vec();
        a.push(out);
        nonholo_in(&root, &a)
    };
    // A missing directory is not created, and nothing runs.
    let o = with_out("missing/deeper/run.json");
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("does not exist"), "{}", stderr(&o));
    assert!(!root.join("missing").exists());

    // A symbolic link is written through; the file keeps its mode.
    #[cfg(unix)]
    {
        use std::os::unix::fs::{PermissionsExt, symlink};
        std::fs::write(root.join("real.json"), "{}").unwrap();
        std::fs::set_permissions(
            root.join("real.json"),
            std::fs::Permissions::from_mode(0o640),
        )
        .unwrap();
        symlink("real.json", root.join("link.json")).unwrap();
        let o = with_out("link.json");
        assert!(o.status.success(), "{}", stderr(&o));
        let link = std::fs::symlink_metadata(root.join("link.json")).unwrap();
        assert!(link.file_type().is_symlink(), "the link was replaced");
        assert!(read(&root.join("real.json")).len() > 100);
        let mode = std::fs::metadata(root.join("real.json"))
            .unwrap()
            .permissions()
            .mode();
        assert_eq!(mode & 0o777, 0o640);
    }

    // A temporary left by a killed write is cleaned up by the next write.
    let stale = root.join(".run.json.999999.tmp");
    std::fs::write(&stale, "half a file").unwrap();
    let o = with_out("run.json");
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stale.exists(), "stale temporary left");

    // CSV and metadata go together: if the metadata cannot be written, the
    // previous CSV is left as it was (and the failure is found before the run).
    std::fs::write(root.join("run.csv"), "previous").unwrap();
    std::fs::create_dir(root.join("run.csv.meta.json")).unwrap();
    let o = with_out("run.csv");
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("run.csv.meta.json"), "{}", stderr(&o));
    assert_eq!(read(&root.join("run.csv")), b"previous");

    // An experiment never writes into a directory of other files.
    let file = experiment(&root, "e", &disk_sweep("e", 2, 1.0));
    std::fs::create_dir(root.join("mine")).unwrap();
    std::fs::write(root.join("mine/notes.txt"), "mine").unwrap();
    std::fs::write(root.join("mine/.draft.tmp"), "mine too").unwrap();
    let o = nonholo_in(&root, &["experiment", &file, "--out", "mine"]);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("`notes.txt`"), "{}", stderr(&o));
    let mut left: Vec<String> = std::fs::read_dir(root.join("mine"))
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, [".draft.tmp", "notes.txt"]);

    // Nor into the results of another experiment.
    let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let other = experiment(&root, "f", &disk_sweep("f", 2, 1.0));
    let o = nonholo_in(&root, &["experiment", &other, "--out", "results/e"]);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("holds the results of experiment `e`, not `f`"),
        "{}",
        stderr(&o)
    );
}

// Item 9: no NaN, infinity or 160-digit number in a result file.
#[test]
fn no_nan_and_no_endless_digits_in_results() {
    let root = scratch("rel-nan");
    for (name, table, value) in [("u", "init", "u = 1e160"), ("m", "params", "m = 1e308")] {
        let body = format!(
            r#"[experiment]
name = "{name}"
title = "t"
claim = "c"
scene = "sleigh-incline"

[{table}]
{value}

[time]
t_end = 1.0
output_every = 0.1

[[formulation]]
label = "B"
formulation = "chetaev"

[[formulation]]
label = "C"
formulation = "vakonomic"
"#
        );
        let file = experiment(&root, name, &body);
        let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
        assert_no_panic(&o);
        let dir = root.join("results").join(name);
        assert!(dir.join("runs.csv").exists(), "{name}: {}", stderr(&o));
        let bad = bad_numbers(&dir);
        assert!(bad.is_empty(), "{name}: {bad:?}");
        let runs = String::from_utf8(read(&dir.join("runs.csv"))).unwrap();
        for l in runs.lines().skip(1) {
            assert!(l.contains(",failed,"), "{name}: {l}");
            assert!(
                l.contains("at t = "),
                "{name}: a failure names its time: {l}"
            );
        }
    }
    let o = nonholo_in(
        &root,
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--param",
            "m=1e308",
            "--t-end",
            "1",
            "--out",
            "m.csv",
        ],
    );
    assert_eq!(code(&o), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("at t = 0"), "{}", stderr(&o));
    assert!(!root.join("m.csv").exists() && !root.join("m.csv.meta.json").exists());
    let o = nonholo_in(
        &root,
        &[
            "simulate",
            "--scene",
            "sleigh-incline",
            "--init",
            "u=1e160",
            "--t-end",
            "1",
            "--out",
            "u.csv",
        ],
    );
    assert_eq!(code(&o), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("not finite"), "{}", stderr(&o));
    assert!(!root.join("u.csv").exists() && !root.join("u.csv.meta.json").exists());
}

fn plot_fixture(tag: &str) -> (std::path::PathBuf, String) {
    let root = scratch(tag);
    let file = experiment(&root, "p", &disk_sweep("p", 3, 1.0));
    let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
    assert!(o.status.success(), "{}", stderr(&o));
    (root, file)
}

// Item 10: `plot` refuses what it cannot draw faithfully; `reproduce`
// checks everything before it runs anything.
#[test]
fn plot_refuses_stale_missing_or_corrupt_results() {
    let (root, file) = plot_fixture("rel-plot-stale");
    assert!(nonholo_in(&root, &["plot", &file]).status.success());
    let text = std::fs::read_to_string(root.join(&file)).unwrap();
    std::fs::write(
        root.join(&file),
        text.replace("rtol = 1e-12", "rtol = 1e-11"),
    )
    .unwrap();
    let o = nonholo_in(&root, &["plot", &file]);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("points/0.json"), "{}", stderr(&o));

    let (root, file) = plot_fixture("rel-plot-missing");
    std::fs::remove_file(root.join("results/p/trajectories/0-C.csv")).unwrap();
    let o = nonholo_in(&root, &["plot", &file]);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("0-C.csv: missing"), "{}", stderr(&o));

    let (root, file) = plot_fixture("rel-plot-corrupt");
    let t = root.join("results/p/trajectories/0-B.csv");
    let text = std::fs::read_to_string(&t).unwrap();
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut fields: Vec<&str> = lines[3].split(',').collect();
    fields[1] = "x1.5";
    lines[3] = fields.join(",");
    std::fs::write(&t, lines.join("\n") + "\n").unwrap();
    let o = nonholo_in(&root, &["plot", &file]);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("0-B.csv:4: column `x`: `x1.5` is not a number"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn reproduce_checks_everything_first_and_links_right() {
    let root = scratch("rel-reproduce");
    std::fs::create_dir_all(root.join("docs")).unwrap();
    // No figure experiment at all: nothing to reproduce, no table written.
    std::fs::create_dir_all(root.join("experiments")).unwrap();
    let o = nonholo_in(&root, &["reproduce", "--threads", "1"]);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("marked as a figure"), "{}", stderr(&o));
    assert!(!root.join("docs/figures.md").exists());
    let good =
        disk_sweep("a", 2, 1.0).replace("claim = \"none\"", "claim = \"none\"\nfigure = true");
    experiment(&root, "a", &good);
    experiment(&root, "b", "[experiment]\nname = \"b\"\n");
    let o = nonholo_in(&root, &["reproduce", "--threads", "1"]);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("b.toml"), "{}", stderr(&o));
    assert!(
        !root.join("results/a").exists(),
        "an experiment ran before the check"
    );

    for bad in ["0", "-1"] {
        let o = nonholo_in(&root, &["reproduce", "--threads", bad]);
        assert_eq!(code(&o), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("--threads"), "{}", stderr(&o));
        assert!(
            !stderr(&o).contains("unexpected argument"),
            "{}",
            stderr(&o)
        );
    }

    // Two files of one name would write one results directory.
    experiment(&root, "b", &good);
    let o = nonholo_in(&root, &["reproduce", "--threads", "1"]);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("are both named `a`"), "{}", stderr(&o));
    assert!(
        !root.join("results/a").exists(),
        "an experiment ran before the check"
    );

    std::fs::remove_file(root.join("experiments/b.toml")).unwrap();
    let abs = root.join("docs/abs.md");
    let elsewhere = root.join("elsewhere");
    std::fs::create_dir_all(&elsewhere).unwrap();
    for (cwd, figures) in [
        (root.clone(), abs.display().to_string()),
        (elsewhere.clone(), "../docs/rel.md".to_string()),
    ] {
        let exps = root.join("experiments").display().to_string();
        let o = nonholo_in(
            &cwd,
            &[
                "reproduce",
                "--threads",
                "1",
                "--experiments",
                &exps,
                "--figures",
                &figures,
            ],
        );
        assert!(o.status.success(), "{figures}: {}", stderr(&o));
        let page_path = cwd.join(&figures);
        let page = std::fs::read_to_string(&page_path).unwrap();
        let links: Vec<&str> = page
            .split("](")
            .skip(1)
            .map(|s| s.split(')').next().unwrap())
            .collect();
        assert!(!links.is_empty(), "{page}");
        for l in links {
            let target = page_path.parent().unwrap().join(l);
            assert!(target.exists(), "{figures}: broken link {l}");
        }
    }
}

// Item 12: the command line and experiment files refuse the same values
// with the same reasons, naming the field.
#[test]
fn messages_name_the_field_and_agree() {
    let fails = |args: &[&str], needles: &[&str]| {
        let o = nonholo(args);
        assert_eq!(code(&o), Some(2), "{args:?}: {}", stderr(&o));
        for n in needles {
            assert!(
                stderr(&o).contains(n),
                "{args:?}: `{n}` not in {}",
                stderr(&o)
            );
        }
    };
    let sim = ["simulate", "--scene", "sleigh-incline"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        sim.iter().copied().chain(extra.iter().copied()).collect()
    };
    fails(
        &with(&["--rtol", "-1e-6"]),
        &["--rtol: must be a positive finite number, got -1e-6"],
    );
    fails(
        &with(&["--atol", "1e-320"]),
        &["--atol: 1e-320 lies outside"],
    );
    fails(
        &with(&["--rtol", "1e300"]),
        &["--rtol: 1e300 is not below 1"],
    );
    fails(
        &with(&["--param", "J=1e300", "--param", "a=1e300"]),
        &["J = 1e300, a = 1e300 violate J > a² = inf"],
    );
    fails(
        &with(&["--step", "0.01", "--rtol", "1e-6"]),
        &["--rtol: has no effect with --step"],
    );
    fails(
        &with(&["--max-steps", "0"]),
        &["--max-steps: must be at least 1"],
    );
    let help = nonholo(&["simulate", "--help"]);
    assert!(String::from_utf8_lossy(&help.stdout).contains("radau5"));

    let root = scratch("rel-messages");
    let base = disk_sweep("m", 2, 1.0);
    // (name, what replaces B's first `old` line, the key refused, its line's text)
    for (name, old, new, key, at) in [
        (
            "steps",
            "atol = 1e-12",
            "atol = 1e-12\nmax_steps = 0",
            "max_steps",
            "max_steps = 0",
        ),
        (
            "atol",
            "atol = 1e-12",
            "atol = 1e-320",
            "atol",
            "atol = 1e-320",
        ),
        (
            "rtol",
            "rtol = 1e-12",
            "rtol = 1e300",
            "rtol",
            "rtol = 1e300",
        ),
        (
            "step",
            "atol = 1e-12",
            "atol = 1e-12\nstep = 0.01",
            "rtol",
            "rtol = 1e-12",
        ),
    ] {
        let body = base.replacen(old, new, 1);
        let file = experiment(&root, name, &body);
        let o = nonholo_in(&root, &["experiment", &file]);
        let e = stderr(&o);
        assert_eq!(code(&o), Some(2), "{name}: {e}");
        let line = body.lines().position(|l| l == at).unwrap() + 1;
        let expected = format!("{file}:{line}: `formulation.{key}`: ");
        assert!(e.contains(&expected), "{name}: `{expected}` not in {e}");
    }
    // The same reason on both sides.
    let cli = stderr(&nonholo(&with(&["--atol", "1e-320"])));
    let toml = stderr(&nonholo_in(&root, &["experiment", "experiments/atol.toml"]));
    let reason = |s: &str| s.split("1e-320").nth(1).map(str::to_string);
    assert_eq!(reason(&cli), reason(&toml), "{cli} / {toml}");
}

/// Sends `signal` (`KILL`, `INT`) to `pid`.
fn signal(pid: u32, signal: &str) {
    let _ = Command::new("kill")
        .args(["-s", signal, &pid.to_string()])
        .status();
}

// Item 3 (and 2, 4, 7): a sweep killed (SIGKILL) or interrupted (SIGINT) at
// random moments and resumed, on another thread count, ends with the bytes
// of an uninterrupted run.
#[test]
fn killed_and_interrupted_sweeps_resume_to_the_same_bytes() {
    let root = scratch("rel-kill");
    let file = experiment(&root, "k", &disk_sweep("k", 24, 60.0));
    let started = Instant::now();
    let o = nonholo_in(
        &root,
        &[
            "experiment",
            &file,
            "--out",
            "fresh",
            "--threads",
            "2",
            "--quiet",
        ],
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let whole = started.elapsed();
    let fresh = comparable(&root.join("fresh"));
    // Deterministic moments spread over (and a little past) a whole run.
    let mut x = 0x9E37_79B9_7F4A_7C15u64;
    // Interrupted runs, by signal (a SIGINT is ignored where the tests run
    // as a background job of a non-interactive shell: such a trial then
    // checks a run that completed).
    let (mut killed, mut stopped_by_int) = (0, 0);
    for trial in 0..10 {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        let at = whole.mul_f64((x % 1000) as f64 / 1000.0 * 1.05);
        let out = format!("trial-{trial}");
        let mut child = Command::new(bin())
            .args([
                "experiment",
                &file,
                "--out",
                &out,
                "--threads",
                "2",
                "--quiet",
            ])
            .current_dir(&root)
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(at);
        let how = if trial % 2 == 0 { "KILL" } else { "INT" };
        signal(child.id(), how);
        let status = child.wait().unwrap();
        if !status.success() {
            if how == "KILL" {
                killed += 1;
            } else {
                stopped_by_int += 1;
            }
        }
        let o = nonholo_in(
            &root,
            &[
                "experiment",
                &file,
                "--out",
                &out,
                "--threads",
                "1",
                "--quiet",
            ],
        );
        assert!(
            o.status.success(),
            "trial {trial} ({how} at {at:?}): {}",
            stderr(&o)
        );
        let resumed = comparable(&root.join(&out));
        for (f, (a, b)) in COMPARABLE.iter().zip(fresh.iter().zip(&resumed)) {
            assert!(
                a == b,
                "trial {trial}: {f} differs after {how} at {at:?} ({status})"
            );
        }
        let left: Vec<_> = walk(&root.join(&out))
            .into_iter()
            .filter(|p| p.to_string_lossy().ends_with(".tmp") || p.ends_with(".nonholo.lock"))
            .collect();
        assert!(left.is_empty(), "trial {trial}: left behind {left:?}");
    }
    eprintln!(
        "interrupted before the end: {killed} of 5 SIGKILL, {stopped_by_int} of 5 SIGINT trials \
         ({whole:?} uninterrupted)"
    );
    assert!(
        killed >= 3,
        "only {killed} of 5 SIGKILL trials hit a running sweep"
    );
}

/// `sleigh-train`'s `N` sets its coordinates: an experiment may fix it in
/// `[params]` (and then runs, its tables named by that train's
/// coordinates), but sweeping it or setting it per formulation is refused
/// at once, naming the field.
#[test]
fn the_size_of_a_scene_is_fixed_per_experiment() {
    let root = scratch("rel-train");
    let head = r#"[experiment]
name = "tr"
title = "t"
claim = "c"
scene = "sleigh-train"

[params]
N = 4

[time]
t_end = 0.2
output_every = 0.05

[[formulation]]
label = "B"
formulation = "chetaev"
"#;
    for (tag, tail, needle) in [
        (
            "sweep",
            "\n[sweep]\nmode = \"grid\"\nvalues = { \"param.N\" = [2, 3] }\n",
            "`sweep.values.param.N`: `N` sets the size of scene `sleigh-train`",
        ),
        (
            "line",
            "params = { N = 5 }\n",
            "`formulation.params.N`: `N` sets the size of scene `sleigh-train`",
        ),
    ] {
        let file = experiment(&root, tag, &format!("{head}{tail}"));
        let o = nonholo_in(&root, &["experiment", &file]);
        assert_no_panic(&o);
        assert_eq!(code(&o), Some(2), "{tag}: {}", stderr(&o));
        assert!(stderr(&o).contains(needle), "{tag}: {}", stderr(&o));
    }
    let file = experiment(&root, "fixed", head);
    let o = nonholo_in(&root, &["experiment", &file, "--quiet"]);
    assert_no_panic(&o);
    assert_eq!(code(&o), Some(0), "{}", stderr(&o));
    let runs = std::fs::read_to_string(root.join("results/tr/runs.csv")).unwrap();
    assert!(runs.contains("completed"), "{runs}");
    // A train larger than its set-up can bear before any budget applies is
    // refused at once, naming the bound.
    let o = nonholo(&[
        "simulate",
        "--scene",
        "sleigh-train",
        "--param",
        "N=10001",
        "--max-wall-time",
        "5",
    ]);
    assert_no_panic(&o);
    assert_eq!(code(&o), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("10000"), "{}", stderr(&o));
}
