//! Sweeps end to end: a sweep file expands into validated runs with stable ids; shards split
//! it with nothing lost or run twice; the local runner skips finished runs, re-does failed
//! ones and resumes killed ones to the same result; collect merges it all into one table.

use std::path::{Path, PathBuf};
use std::process::Command;

mod common;
use common::ifslab;
use ifslab_experiments::progress::{Progress, Silent};
use ifslab_experiments::runs::redraw_pictures;
use ifslab_experiments::sweep::collect::{RunState, collect};
use ifslab_experiments::sweep::local::{RECORD_FILE, RunRecord, partial_dir, run_dir};
use ifslab_experiments::sweep::pack::{DEFAULT_LOG_COLUMNS, Pack, pack, unpack};
use ifslab_experiments::sweep::report::{ReportOptions, write_report};
use ifslab_experiments::sweep::{
    Plan, PlannedRun, RunStatus, RunnerOptions, Shard, SweepConfig, run_sweep, slurm,
};

/// A base config whose runs take seconds: a 32² target, few iterations.
const BASE: &str = r#"
iterations = 12
best_of = 1
checkpoint_every = 3
[target]
code = "sierpinski"
size = 32
[model]
maps = 3
init = "em"
[generator]
trajectories = 100
length = 40
warmup = 10
[renderer]
supersample = 2
"#;

fn plan(dir: &Path, sweep: &str) -> ifslab_experiments::Result<Plan> {
    std::fs::write(dir.join("base.toml"), BASE).unwrap();
    let path = dir.join("sweep.toml");
    std::fs::write(&path, sweep).unwrap();
    Plan::load(&path)
}

fn err(dir: &Path, sweep: &str) -> String {
    format!("{:#}", plan(dir, sweep).unwrap_err())
}

fn silent(_: &PlannedRun) -> Box<dyn Progress> {
    Box::new(Silent)
}

/// A summary without its wall-time field.
fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).unwrap();
    let mut v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v.as_object_mut().unwrap().remove("seconds");
    v
}

#[test]
fn axes_expand_in_order_with_labels_and_stable_ids() {
    let tmp = tempfile::tempdir().unwrap();
    let sweep = r#"
base = "base.toml"
[set]
iterations = 7
[[axis]]
name = "strategy"
[[axis.value]]
label = "adam"
set = { "strategy.kind" = "adam" }
[[axis.value]]
label = "hybrid"
set = { strategy = { kind = "hybrid", anneal_every = 3 } }
[[axis]]
key = "seed"
values = [0, 1, 2]
labels = ["s0", "s1", "s2"]
"#;
    let p = plan(tmp.path(), sweep).unwrap();
    assert_eq!(p.axes, ["strategy", "seed"]);
    let names: Vec<&str> = p.runs.iter().map(|r| r.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "adam-s0",
            "adam-s1",
            "adam-s2",
            "hybrid-s0",
            "hybrid-s1",
            "hybrid-s2"
        ]
    );
    // The overrides reached the configs: [set], a dotted key, a nested table.
    let r4 = &p.runs[4].resolved;
    assert_eq!(r4["iterations"].as_integer(), Some(7));
    assert_eq!(r4["seed"].as_integer(), Some(1));
    assert_eq!(r4["strategy"]["kind"].as_str(), Some("hybrid"));
    assert_eq!(r4["strategy"]["anneal_every"].as_integer(), Some(3));
    // Ids are distinct, hex, and the same when the sweep is read again.
    let ids: Vec<String> = p.runs.iter().map(|r| r.id.clone()).collect();
    assert!(
        ids.iter()
            .all(|id| id.len() == 16 && id.chars().all(|c| c.is_ascii_hexdigit()))
    );
    let again = plan(tmp.path(), sweep).unwrap();
    assert_eq!(
        ids,
        again.runs.iter().map(|r| r.id.clone()).collect::<Vec<_>>()
    );
    // An id belongs to the resolved config, not to the sweep that produced it: the same run
    // written as the base itself, with defaults spelt out and no axes, has the same id.
    let single = r#"
base = "base.toml"
[set]
iterations = 7
seed = 1
strategy = { kind = "hybrid", anneal_every = 3 }
"#;
    let one = plan(tmp.path(), single).unwrap();
    assert_eq!(one.runs.len(), 1);
    assert_eq!(one.runs[0].id, ids[4]);
    // A changed value is a different run.
    let other = plan(
        tmp.path(),
        &sweep.replace("iterations = 7", "iterations = 8"),
    )
    .unwrap();
    assert!(other.runs.iter().all(|r| !ids.contains(&r.id)));
}

#[test]
fn bad_sweeps_are_refused_naming_the_run_and_key() {
    let tmp = tempfile::tempdir().unwrap();
    // A value the run config rejects: the message names the run, its labels and the key.
    let e = err(
        tmp.path(),
        "base = \"base.toml\"\n[[axis]]\nkey = \"renderer.sigma\"\nvalues = [1.0, -2.0]\n",
    );
    assert!(
        e.contains("run 1 (renderer.sigma=-2.0)") && e.contains("renderer.sigma"),
        "{e}"
    );
    // An unknown key.
    let e = err(
        tmp.path(),
        "base = \"base.toml\"\n[[axis]]\nkey = \"model.mpas\"\nvalues = [2, 3]\n",
    );
    assert!(e.contains("run 0") && e.contains("mpas"), "{e}");
    // A key below a value that is not a table.
    let e = err(
        tmp.path(),
        "base = \"base.toml\"\n[[axis]]\nkey = \"iterations.x\"\nvalues = [2, 3]\n",
    );
    assert!(e.contains("`iterations` is 12, not a table"), "{e}");
    // An axis that changes nothing: two runs, one config.
    let e = err(
        tmp.path(),
        "base = \"base.toml\"\n[[axis]]\nkey = \"seed\"\nvalues = [0, 0]\nlabels = [\"a\", \"b\"]\n",
    );
    assert!(e.contains("resolve to the same config"), "{e}");
    // Malformed axes and fields of the sweep file itself.
    for (sweep, expect) in [
        (
            "base = \"base.toml\"\n[[axis]]\nkey = \"seed\"\n",
            "has no values",
        ),
        (
            "base = \"base.toml\"\n[[axis]]\nkey = \"seed\"\nvalues = [1]\nlabels = [\"a\", \"b\"]\n",
            "2 labels for 1 values",
        ),
        (
            "base = \"base.toml\"\n[[axis]]\nvalues = [1]\n",
            "needs the `key`",
        ),
        ("base = \"base.toml\"\nbogus = 1\n", "bogus"),
        ("base = \"missing.toml\"\n", "missing.toml"),
        (
            "base = \"base.toml\"\n[[axis]]\nkey = \"seed\"\nvalues = [1, 2]\n[[axis]]\nkey = \"seed\"\nvalues = [3]\n",
            "two axes are called `seed`",
        ),
        (
            "base = \"base.toml\"\n[slurm]\nshards = 0\n",
            "slurm.shards",
        ),
    ] {
        let e = err(tmp.path(), sweep);
        assert!(e.contains(expect), "expected `{expect}` in: {e}");
    }
    // Bad shards.
    for bad in ["3/2", "1/0", "x/2", "2"] {
        assert!(bad.parse::<Shard>().is_err(), "{bad}");
    }
}

#[test]
fn groups_and_folder_axes_expand_to_their_union() {
    let tmp = tempfile::tempdir().unwrap();
    let targets = tmp.path().join("targets");
    std::fs::create_dir(&targets).unwrap();
    for name in ["b", "a"] {
        image::GrayImage::from_fn(40, 40, |x, y| {
            image::Luma([if (x / 5 + y / 5) % 2 == 0 { 255 } else { 0 }])
        })
        .save(targets.join(format!("{name}.png")))
        .unwrap();
    }
    std::fs::write(targets.join("notes.txt"), "not an image").unwrap();
    let sweep = r#"
base = "base.toml"
[[axis]]
key = "seed"
values = [0, 1]
[[group]]
name = "codes"
[[group.axis]]
key = "target.code"
name = "target"
values = ["sierpinski", "fern"]
[[group]]
name = "images"
set = { target = { code = false } }
[[group.axis]]
key = "target.image"
name = "target"
folder = "targets"
"#;
    // `code = false` is not a code: the override is refused with the run named.
    let e = err(tmp.path(), sweep);
    assert!(e.contains("group=images"), "{e}");
    // Removing the base's code is the base's business: an image group needs a base without one.
    std::fs::write(
        tmp.path().join("base.toml"),
        BASE.replace("code = \"sierpinski\"\n", ""),
    )
    .unwrap();
    let path = tmp.path().join("sweep.toml");
    std::fs::write(
        &path,
        sweep
            .replace("set = { target = { code = false } }\n", "")
            .replace(
                "[[group.axis]]\nkey = \"target.code\"",
                "set = { \"target.code\" = \"x\" }\n[[group.axis]]\nkey = \"target.code\"",
            ),
    )
    .unwrap();
    let p = Plan::load(&path).unwrap();
    assert_eq!(p.axes, ["group", "seed", "target"]);
    let names: Vec<&str> = p.runs.iter().map(|r| r.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "codes-0-sierpinski",
            "codes-0-fern",
            "codes-1-sierpinski",
            "codes-1-fern",
            "images-0-a",
            "images-0-b",
            "images-1-a",
            "images-1-b"
        ]
    );
    let img = p.runs[4].resolved["target"]["image"].as_str().unwrap();
    assert!(
        Path::new(img).is_absolute() && img.ends_with("a.png"),
        "{img}"
    );
    // Shards split the sweep: every run in exactly one shard.
    for n in 1..=5 {
        let mut seen = vec![0; p.runs.len()];
        for i in 0..n {
            let s = Shard::new(i, n).unwrap();
            for r in p.runs.iter().filter(|r| s.contains(r.index)) {
                seen[r.index] += 1;
            }
        }
        assert!(seen.iter().all(|&c| c == 1), "{n} shards: {seen:?}");
    }
}

#[test]
fn runner_skips_finished_redoes_failed_and_collect_merges_shards() {
    let tmp = tempfile::tempdir().unwrap();
    let targets = tmp.path().join("targets");
    std::fs::create_dir(&targets).unwrap();
    // A white triangle on black.
    image::GrayImage::from_fn(40, 40, |x, y| {
        let inside = (8..32).contains(&y) && (x as i32 - 20).abs() <= (y as i32 - 8) / 2;
        image::Luma([if inside { 255 } else { 0 }])
    })
    .save(targets.join("a_good.png"))
    .unwrap();
    // A white square on black.
    image::GrayImage::from_fn(40, 40, |x, y| {
        let inside = (12..28).contains(&x) && (12..28).contains(&y);
        image::Luma([if inside { 255 } else { 0 }])
    })
    .save(targets.join("c_good.png"))
    .unwrap();
    // Passes validation (the file exists) and fails when the run reads it.
    std::fs::write(
        targets.join("b_corrupt.png"),
        b"\x89PNG\r\n\x1a\nnot really",
    )
    .unwrap();
    std::fs::write(
        tmp.path().join("base.toml"),
        BASE.replace("code = \"sierpinski\"\n", ""),
    )
    .unwrap();
    let path = tmp.path().join("sweep.toml");
    std::fs::write(
        &path,
        r#"
base = "base.toml"
[[axis]]
key = "target.image"
name = "target"
folder = "targets"
[[axis]]
key = "strategy.kind"
name = "strategy"
values = ["adam", "cold_hybrid"]
"#,
    )
    .unwrap();
    let p = Plan::load(&path).unwrap();
    // Targets a_good, b_corrupt, c_good × strategies adam, cold_hybrid.
    assert_eq!(p.runs.len(), 6);
    let out = tmp.path().join("out");

    // Shard 0 of 2: runs 0, 2 (the corrupt target) and 4.
    let opts = RunnerOptions::new(1, Some(2), Shard::new(0, 2).unwrap()).unwrap();
    let o = run_sweep(&p, &out, &opts, &Silent, &silent).unwrap();
    assert_eq!(o.runs.iter().map(|r| r.0).collect::<Vec<_>>(), [0, 2, 4]);
    assert!(matches!(o.runs[0].1, RunStatus::Finished(_)), "{o:?}");
    assert!(matches!(o.runs[2].1, RunStatus::Finished(_)), "{o:?}");
    let fails = o.failures();
    assert_eq!(fails.len(), 1);
    assert!(
        fails[0].1.contains("not a readable image"),
        "{}",
        fails[0].1
    );
    // The failure left a partial folder with its error, nothing that looks finished.
    let bad = &p.runs[2].id;
    assert!(partial_dir(&out, bad).join("error.txt").is_file());
    assert!(!run_dir(&out, bad).exists());

    // A task that died before its first checkpoint left a half-written folder: the run
    // starts again from nothing.
    let killed = &p.runs[1].id;
    std::fs::create_dir_all(partial_dir(&out, killed)).unwrap();
    std::fs::write(
        partial_dir(&out, killed).join("log.csv"),
        "iter,loss\n0,1\n",
    )
    .unwrap();

    // A collect in between sees every state.
    let c = collect(&out).unwrap();
    let states: Vec<&str> = c.rows.iter().map(|r| r.state.word()).collect();
    assert_eq!(
        states,
        [
            "finished",
            "interrupted",
            "failed",
            "missing",
            "finished",
            "missing"
        ]
    );

    // The whole sweep (2 at a time): finished runs are skipped, the others run, the
    // corrupt ones fail (again).
    let first = std::fs::read(run_dir(&out, &p.runs[0].id).join(RECORD_FILE)).unwrap();
    let opts = RunnerOptions::new(2, Some(1), Shard::ALL).unwrap();
    let o = run_sweep(&p, &out, &opts, &Silent, &silent).unwrap();
    let words: Vec<&str> = o
        .runs
        .iter()
        .map(|(_, s)| match s {
            RunStatus::Skipped => "skipped",
            RunStatus::Finished(_) => "finished",
            RunStatus::Failed(_) => "failed",
            RunStatus::Busy => "busy",
            RunStatus::Interrupted => "interrupted",
        })
        .collect();
    assert_eq!(
        words,
        [
            "skipped", "finished", "failed", "failed", "skipped", "finished"
        ]
    );
    assert_eq!(
        first,
        std::fs::read(run_dir(&out, &p.runs[0].id).join(RECORD_FILE)).unwrap(),
        "a finished run is not touched"
    );
    assert!(!partial_dir(&out, killed).exists());
    let rec: RunRecord =
        serde_json::from_slice(&std::fs::read(run_dir(&out, killed).join(RECORD_FILE)).unwrap())
            .unwrap();
    assert!(!rec.resumed, "no checkpoint to resume from");
    assert_eq!(
        rec.labels[1],
        ("strategy".to_string(), "cold_hybrid".to_string())
    );

    // Collect: one row per planned run, the aggregate is the mean of the runs' summaries.
    let c = collect(&out).unwrap();
    assert_eq!(c.axes, ["target", "strategy"]);
    assert_eq!(c.counts(), (4, 2, 0, 0));
    assert!(matches!(&c.rows[2].state, RunState::Failed(e) if e.contains("not a readable image")));
    let iou = |k: usize| {
        summary(&run_dir(&out, &p.runs[k].id))["iou"]
            .as_f64()
            .unwrap()
    };
    let agg = c.aggregate(&["strategy".to_string()]).unwrap();
    let m = agg.metrics.iter().position(|m| m == "iou").unwrap();
    for (g, (a, b)) in [(0, 4), (1, 5)].into_iter().enumerate() {
        let (_, n, stats) = &agg.groups[g];
        assert_eq!(*n, 3);
        let st = stats[m].unwrap();
        assert_eq!(st.count, 2, "the failed run has no numbers");
        assert!((st.mean - 0.5 * (iou(a) + iou(b))).abs() < 1e-12);
        assert!((st.std - (iou(a) - iou(b)).abs() / 2f64.sqrt()).abs() < 1e-12);
    }
    assert_eq!(agg.groups[0].0, ["adam"]);
    assert!(c.aggregate(&["nope".to_string()]).is_err());

    // Paired: cold_hybrid against adam target by target; the corrupt target pairs nothing.
    let (by, on) = (vec!["strategy".to_string()], vec!["target".to_string()]);
    let pd = c.paired(&by, &on, "adam", "iou").unwrap();
    assert_eq!(pd.rows.len(), 1);
    let r = &pd.rows[0];
    assert_eq!((r.group.as_str(), r.pairs), ("cold_hybrid", 2));
    let d = [iou(1) - iou(0), iou(5) - iou(4)];
    assert!((r.mean_difference - (d[0] + d[1]) / 2.0).abs() < 1e-12);
    assert!((r.standard_error - (d[0] - d[1]).abs() / 2.0).abs() < 1e-12);
    assert_eq!(r.higher, d.iter().filter(|x| **x > 0.0).count());
    assert_eq!(r.lower, d.iter().filter(|x| **x < 0.0).count());
    assert_eq!(r.higher + r.lower + r.equal, 2);
    assert!(
        c.paired(&by, &by, "adam", "iou").is_err(),
        "pairing on the grouping axis"
    );
    assert!(
        c.paired(&by, &on, "nope", "iou").is_err(),
        "an unknown reference"
    );

    // The report: tables, plots, picture grid.
    let report_dir = tmp.path().join("report");
    let opts = ReportOptions {
        by: vec![
            vec!["strategy".into()],
            vec!["target".into(), "strategy".into()],
        ],
        versus: Some("adam".into()),
        ..Default::default()
    };
    let report = write_report(&c, &report_dir, &opts).unwrap();
    let md = std::fs::read_to_string(report).unwrap();
    assert!(
        md.contains("### Paired against adam") && md.contains("Runs paired on target"),
        "{md}"
    );
    assert!(md.contains("| cold_hybrid | 2 |"), "{md}");
    assert!(md.contains("6 runs: 4 finished, 2 failed"), "{md}");
    assert!(md.contains("## By target × strategy"), "{md}");
    assert!(md.contains("| a_good | cold_hybrid |"), "{md}");
    for f in [
        "results.csv",
        "results.json",
        "aggregate_strategy.csv",
        "aggregate_target_strategy.csv",
        "paired_strategy.csv",
        "iou_by_strategy.png",
        "loss_by_strategy.png",
        "pictures.png",
    ] {
        assert!(report_dir.join(f).is_file(), "{f} missing");
    }
    let csv = std::fs::read_to_string(report_dir.join("results.csv")).unwrap();
    assert_eq!(csv.lines().count(), 7);
    assert!(
        csv.lines()
            .next()
            .unwrap()
            .starts_with("id,name,problem,status,target,strategy,")
    );
    let bad_metric = ReportOptions {
        metrics: vec!["nope".into()],
        ..Default::default()
    };
    assert!(write_report(&c, &report_dir, &bad_metric).is_err());
    let bad_reference = ReportOptions {
        versus: Some("nope".into()),
        ..Default::default()
    };
    let e = write_report(&c, &report_dir, &bad_reference).unwrap_err();
    assert!(format!("{e:#}").contains("adam"), "{e:#}");
}

#[test]
fn a_killed_or_signalled_sweep_resumes_to_the_uninterrupted_result() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("base.toml"),
        BASE.replace("iterations = 12", "iterations = 400"),
    )
    .unwrap();
    let sweep = tmp.path().join("sweep.toml");
    // Two seeds, of which only the second is run (`--only`): runs keep their positions in
    // the whole sweep.
    std::fs::write(
        &sweep,
        "base = \"base.toml\"\n[set]\nstrategy.kind = \"adam\"\n[[axis]]\nkey = \"seed\"\nvalues = [0, 1]\n",
    )
    .unwrap();
    let s = sweep.to_string_lossy().into_owned();
    let p = Plan::load(&sweep).unwrap();
    let id = &p.runs[1].id;
    let killed: PathBuf = tmp.path().join("killed");
    let k = killed.to_string_lossy().into_owned();

    // Kill the sweep once its run has written a checkpoint (a node failure, say).
    let mut child = Command::new(env!("CARGO_BIN_EXE_ifslab"))
        .args(["sweep", &s, "-o", &k, "--only", "seed=1", "--threads", "2"])
        .spawn()
        .unwrap();
    let ckpt = partial_dir(&killed, id).join("checkpoint.json");
    let t0 = std::time::Instant::now();
    while !ckpt.is_file() && t0.elapsed().as_secs() < 300 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(ckpt.is_file(), "the run wrote no checkpoint");
    assert!(!run_dir(&killed, id).exists(), "killed before it finished");
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &k, "--only", "seed=1", "--dry-run"]);
    assert!(ok && msg.contains("0 finished, 1 interrupted"), "{msg}");

    // Run again on one thread: it resumes from the checkpoint…
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &k, "--only", "seed=1", "--threads", "1"]);
    assert!(ok, "{msg}");
    let rec: RunRecord =
        serde_json::from_slice(&std::fs::read(run_dir(&killed, id).join(RECORD_FILE)).unwrap())
            .unwrap();
    assert!(rec.resumed, "{rec:?}");
    // …to exactly the result of an uninterrupted run.
    let whole = tmp.path().join("whole");
    let w = whole.to_string_lossy().into_owned();
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &w, "--only", "seed=1"]);
    assert!(ok, "{msg}");
    assert_eq!(
        summary(&run_dir(&killed, id)),
        summary(&run_dir(&whole, id))
    );
    // SIGTERM (Slurm's time limit, a shutdown) instead: the run stops at the end of its
    // iteration with a checkpoint of it, is not marked failed, and resumes to the same end.
    let termed = tmp.path().join("termed");
    let t = termed.to_string_lossy().into_owned();
    let child = Command::new(env!("CARGO_BIN_EXE_ifslab"))
        .args(["sweep", &s, "-o", &t, "--only", "seed=1", "--threads", "2"])
        .env("RUST_BACKTRACE", "0")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let ckpt = partial_dir(&termed, id).join("checkpoint.json");
    let t0 = std::time::Instant::now();
    while !ckpt.is_file() && t0.elapsed().as_secs() < 300 {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let (ok, err) = common::signal_and_wait(child, "-TERM");
    assert!(!ok && err.contains("interrupted"), "{err}");
    assert!(
        !run_dir(&termed, id).exists(),
        "stopped before it finished: {err}"
    );
    assert!(
        !partial_dir(&termed, id).join("error.txt").exists(),
        "marked failed"
    );
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &t, "--only", "seed=1"]);
    assert!(ok, "{msg}");
    assert_eq!(
        summary(&run_dir(&termed, id)),
        summary(&run_dir(&whole, id))
    );
    // A third call has nothing to do.
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &w, "--only", "seed=1"]);
    assert!(
        ok && msg.contains("0 finished now, 1 already done"),
        "{msg}"
    );
    // The resolved config of a run, by name.
    let (ok, msg) = ifslab(&["sweep", &s, "--show", "1"]);
    assert!(
        ok && msg.contains("seed = 1") && msg.contains("kind = \"adam\""),
        "{msg}"
    );
}

#[test]
fn a_sweep_that_needs_missing_lpips_weights_refuses_to_start() {
    let tmp = tempfile::tempdir().unwrap();
    // The runs weigh LPIPS from a weights file that is not there.
    std::fs::write(
        tmp.path().join("base.toml"),
        format!(
            "{BASE}[loss]\nlpips_weight = 2.0\nlpips_weights = \"nowhere/lpips.safetensors\"\n"
        ),
    )
    .unwrap();
    let sweep = tmp.path().join("sweep.toml");
    std::fs::write(
        &sweep,
        "base = \"base.toml\"\n[[axis]]\nkey = \"seed\"\nvalues = [0, 1]\n",
    )
    .unwrap();
    let p = Plan::load(&sweep).unwrap();
    assert!(
        p.runs.iter().all(|r| r
            .config
            .missing_lpips_weights()
            .is_some_and(|m| m.ends_with("nowhere/lpips.safetensors"))),
        "both runs lack their weights file"
    );
    let s = sweep.to_string_lossy().into_owned();
    let out = tmp.path().join("out");
    let o = out.to_string_lossy().into_owned();
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &o]);
    assert!(!ok, "{msg}");
    assert!(
        msg.contains("2 runs of the sweep")
            && msg.contains("nowhere/lpips.safetensors")
            && msg.contains("--without-lpips"),
        "{msg}"
    );
    assert!(!out.join("runs").exists(), "nothing was run");
    // The Slurm script is not written either; a dry run still lists the runs.
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &o, "--slurm"]);
    assert!(!ok && msg.contains("no LPIPS weights"), "{msg}");
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &o, "--dry-run"]);
    assert!(ok && msg.contains("2 runs"), "{msg}");
    // Asked for on the submitting machine, the array tasks are asked for it too.
    let o2 = tmp.path().join("slurm_out").to_string_lossy().into_owned();
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &o2, "--slurm", "--without-lpips"]);
    assert!(ok, "{msg}");
    let script = std::fs::read_to_string(Path::new(&o2).join("slurm/sweep.sbatch")).unwrap();
    assert!(
        script
            .lines()
            .any(|l| l.contains(" sweep ") && l.contains("--without-lpips")),
        "{script}"
    );
    // Asked for, the runs go without the term and say so in their summaries.
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &o, "--only", "seed=1", "--without-lpips"]);
    assert!(ok, "{msg}");
    let done = summary(&run_dir(&out, &p.runs[1].id));
    assert!(
        done["lpips_note"]
            .as_str()
            .is_some_and(|n| n.contains("LPIPS term skipped")),
        "{done}"
    );
    // The report says so: a table of such runs is not the method its labels name.
    let (ok, msg) = ifslab(&["collect", &o]);
    assert!(
        ok && msg.contains("warning: notes in the runs' summaries"),
        "{msg}"
    );
    let report = std::fs::read_to_string(out.join("report/report.md")).unwrap();
    assert!(
        report.contains("Runs that left notes in their summaries: 1**")
            && report.contains("lpips_note: LPIPS term skipped")
            && report.contains("## Notes")
            && report.contains(&p.runs[1].id),
        "{report}"
    );
    // Once finished, a run needs no weights: only the unfinished one is counted.
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &o]);
    assert!(
        !ok && msg.contains("1 run of the sweep weighs LPIPS in its loss"),
        "{msg}"
    );
    // The library's runner refuses too: a program calling `run_sweep` is protected.
    let opts = RunnerOptions::new(1, Some(1), Shard::ALL).unwrap();
    let err = run_sweep(&p, &out, &opts, &Silent, &silent).unwrap_err();
    assert!(err.to_string().contains("no LPIPS weights"), "{err}");
}

#[test]
fn the_slurm_script_runs_one_shard_per_array_task() {
    let tmp = tempfile::tempdir().unwrap();
    let sweep = r#"
name = "my sweep"
base = "base.toml"
[[axis]]
key = "seed"
values = [0, 1, 2, 3, 4]
[slurm]
shards = 2
max_parallel = 1
time = "00:10:00"
cpus_per_task = 3
mem = "2G"
partition = "debug"
extra = ["--constraint=avx2"]
setup = ["module load rust"]
"#;
    let p = plan(tmp.path(), sweep).unwrap();
    let out = tmp.path().join("out");
    let script = slurm::write_script(&p, &out, Path::new("/opt/ifslab"), &[]).unwrap();
    let text = std::fs::read_to_string(&script).unwrap();
    for line in [
        "#SBATCH --job-name=my_sweep",
        "#SBATCH --array=0-1%1",
        "#SBATCH --requeue",
        "#SBATCH --time=00:10:00",
        "#SBATCH --cpus-per-task=3",
        "#SBATCH --mem=2G",
        "#SBATCH --partition=debug",
        "#SBATCH --constraint=avx2",
        "#SBATCH --signal=B:USR1@120",
        "module load rust",
        "--shard \"${SLURM_ARRAY_TASK_ID}/2\"",
        "--threads \"${SLURM_CPUS_PER_TASK:-3}\"",
        "scontrol requeue",
    ] {
        assert!(text.contains(line), "`{line}` missing from:\n{text}");
    }
    assert!(text.starts_with("#!/bin/bash\n"));
    assert!(out.join("sweep.json").is_file());
    // The script is valid shell.
    let ok = Command::new("bash")
        .arg("-n")
        .arg(&script)
        .status()
        .unwrap()
        .success();
    assert!(ok, "{text}");
    // Without shards in the config: one task per run.
    let p = plan(tmp.path(), &sweep.replace("shards = 2\n", "")).unwrap();
    assert_eq!(slurm::shard_count(&p), 5);
    // --submit without --slurm is refused; --slurm alone writes the script.
    let s = tmp.path().join("sweep.toml").to_string_lossy().into_owned();
    let o = out.to_string_lossy().into_owned();
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &o, "--submit"]);
    assert!(!ok && msg.contains("--slurm"), "{msg}");
    let (ok, msg) = ifslab(&["sweep", &s, "-o", &o, "--slurm"]);
    assert!(ok && msg.contains("5 runs in 5 array tasks"), "{msg}");
    let _ = SweepConfig::load(&tmp.path().join("sweep.toml")).unwrap();
}

#[test]
fn the_chaotic_splatting_sweep_is_the_protocol_its_results_ran() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let repro = root.join("paper_repro/chaotic_splatting");
    let mut p = Plan::load(&repro.join("sweep.toml")).unwrap();
    assert_eq!(p.runs.len(), 87);
    // The committed run folders whose recorded configs are runs of the sweep are taken in
    // as finished runs; the others are named.
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("cs");
    let r = ifslab_experiments::sweep::local::adopt(&p, &out, &repro.join("results/runs")).unwrap();
    // Every committed run is a run of the sweep (the first `hybrid_variance` runs, made with a
    // 1-candidate annealing table, were re-run as the config means today).
    assert_eq!(r.adopted.len(), 87, "{:?}", r.unmatched);
    assert!(r.unmatched.is_empty(), "{:?}", r.unmatched);
    // Every adopted folder went to the run of the same name.
    for (i, from) in &r.adopted {
        assert_eq!(
            from.file_name().unwrap().to_string_lossy(),
            p.runs[*i].name,
            "{}",
            from.display()
        );
    }
    let c = collect(&out).unwrap();
    assert_eq!(c.counts(), (87, 0, 0, 0));
    // A tier of it: --only keeps the runs matching every axis named.
    p.retain(&[
        ("group".into(), "em".into()),
        ("target".into(), "sierpinski".into()),
        ("target".into(), "fern".into()),
    ])
    .unwrap();
    let names: Vec<&str> = p.runs.iter().map(|r| r.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "em-adam-sierpinski-s0",
            "em-adam-fern-s0",
            "em-hybrid-sierpinski-s0",
            "em-hybrid-fern-s0",
            "em-hybrid_sched-sierpinski-s0",
            "em-hybrid_sched-fern-s0"
        ]
    );
    assert!(p.clone().retain(&[("nope".into(), "x".into())]).is_err());
    assert!(p.retain(&[("group".into(), "nope".into())]).is_err());
}

/// A packed sweep folder is the same sweep: the runner skips its runs, `collect` tables them
/// as it tables the folders, and `unpack` + `redraw_pictures` give back the runs' pictures.
#[test]
fn a_packed_sweep_is_skipped_collected_and_unpacked_as_its_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let p = plan(
        tmp.path(),
        "base = \"base.toml\"\n[[axis]]\nkey = \"seed\"\nvalues = [0, 1]\n",
    )
    .unwrap();
    let out = tmp.path().join("out");
    let opts = RunnerOptions::new(1, None, Shard::ALL).unwrap();
    run_sweep(&p, &out, &opts, &Silent, &silent).unwrap();
    let id = p.runs[1].id.clone();
    let render = std::fs::read(run_dir(&out, &id).join("render.png")).unwrap();
    let zoom = std::fs::read(run_dir(&out, &id).join("zoom_strip.png")).unwrap();
    let report = |to: &str| {
        let dir = tmp.path().join(to);
        write_report(&collect(&out).unwrap(), &dir, &ReportOptions::default()).unwrap();
        dir
    };
    let folders = report("from_folders");
    let keep: Vec<String> = DEFAULT_LOG_COLUMNS.iter().map(|c| c.to_string()).collect();
    let packed = pack(&out.join("runs"), &keep, true).unwrap();
    assert_eq!((packed.runs, packed.removed), (2, 2));
    assert!(!run_dir(&out, &id).exists());
    let o = run_sweep(&p, &out, &opts, &Silent, &silent).unwrap();
    assert_eq!(o.skipped(), 2, "packed runs are finished runs");
    let from_pack = report("from_pack");
    for f in ["results.csv", "results.json", "aggregate_seed.csv"] {
        assert_eq!(
            std::fs::read_to_string(folders.join(f)).unwrap(),
            std::fs::read_to_string(from_pack.join(f)).unwrap(),
            "{f}"
        );
    }
    // The report differs only where the pictures were: it says how to draw them.
    let md = std::fs::read_to_string(from_pack.join("report.md")).unwrap();
    assert!(md.contains("ifslab unpack DIR --pictures"), "{md}");
    assert!(
        from_pack.join("loss_by_seed.png").is_file(),
        "loss curves from the pack"
    );
    let u = unpack(&out.join("runs"), std::slice::from_ref(&id)).unwrap();
    assert_eq!(u.written, 1);
    redraw_pictures(&run_dir(&out, &id)).unwrap();
    assert_eq!(
        std::fs::read(run_dir(&out, &id).join("render.png")).unwrap(),
        render
    );
    assert_eq!(
        std::fs::read(run_dir(&out, &id).join("zoom_strip.png")).unwrap(),
        zoom
    );
}

/// Table 3 and Table 4 of the chaotic-splatting paper are sweeps over the random suite, and
/// the committed medium-tier runs (packed: `runs.jsonl.gz`) are finished runs of each table
/// (their ids are the runs' resolved configs), which `collect` merges whole.
#[test]
fn the_table_sweeps_expand_and_their_committed_runs_are_theirs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let repro = root.join("paper_repro/chaotic_splatting");
    let t3 = Plan::load(&repro.join("table3.toml")).unwrap();
    assert_eq!(t3.runs.len(), 11 * 100);
    let t4 = Plan::load(&repro.join("table4.toml")).unwrap();
    // The paper's ten ablations, its recipe, and the naive row with the regulariser ×10.
    assert_eq!(t4.runs.len(), 12 * 50);
    // The Table 4 baseline row is Table 3's paper recipe: the same runs, the same ids.
    assert_eq!(t3.runs[0].id, t4.runs[0].id);
    // Table 3's rows that start from a random code, the start drawn per run, on 30 codes:
    // ours_paper, ours_basin, the four value-only baselines and Learning Fractals twice.
    let t3s = Plan::load(&repro.join("table3_starts.toml")).unwrap();
    assert_eq!(t3s.runs.len(), 8 * 30);
    // Table 4's twelve rows the same way; its `ours` row is Table 3's `ours_paper` there.
    let t4s = Plan::load(&repro.join("table4_starts.toml")).unwrap();
    assert_eq!(t4s.runs.len(), 12 * 30);
    let t3s_ids: std::collections::HashSet<&str> = t3s.runs.iter().map(|r| r.id.as_str()).collect();
    let shared = t4s
        .runs
        .iter()
        .filter(|r| t3s_ids.contains(r.id.as_str()))
        .count();
    assert_eq!(
        shared, 30,
        "table4_starts' ours row is table3_starts' ours_paper"
    );
    // The tables are complete: every run of each sweep file is committed, and nothing else.
    for (plan, folder) in [
        (&t3, "table3_medium"),
        (&t4, "table4_medium"),
        (&t3s, "table3_starts"),
        (&t4s, "table4_starts"),
    ] {
        let done = repro.join("results").join(folder);
        let ids: std::collections::HashSet<&str> =
            plan.runs.iter().map(|r| r.id.as_str()).collect();
        let mut committed: Vec<String> = Pack::beside(&done.join("runs"))
            .unwrap()
            .runs
            .iter()
            .map(|r| r.name.clone())
            .collect();
        // Folders written back by `ifslab unpack` are the same runs.
        if let Ok(rd) = std::fs::read_dir(done.join("runs")) {
            for e in rd {
                let name = e.unwrap().file_name().to_string_lossy().into_owned();
                // A sweep's lock folder or a run under way is not a run.
                if !name.starts_with('.') && !committed.contains(&name) {
                    committed.push(name);
                }
            }
        }
        for name in &committed {
            assert!(
                ids.contains(name.as_str()),
                "{name} is not a run of {folder}'s sweep file"
            );
        }
        assert_eq!(committed.len(), plan.runs.len(), "{folder}: committed runs");
        let c = collect(&done).unwrap();
        assert_eq!(c.counts(), (committed.len(), 0, 0, 0), "{folder}");
        assert_eq!(c.unplanned, 0, "{folder}");
    }
}

/// The committed reports are `collect` of the committed runs, as the READMEs regenerate
/// them: a number of a table that no longer matches its runs fails here.
#[test]
fn the_committed_reports_are_collect_of_their_committed_runs() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let results = root.join("paper_repro/chaotic_splatting/results");
    let metrics = |m: &[&str]| m.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let suite = metrics(&[
        "suite.f1",
        "suite.iou",
        "suite.psnr",
        "suite.ssim",
        "suite.lpips",
        "suite.psnr_crop",
        "suite.ssim_crop",
        "seconds",
    ]);
    let tmp = tempfile::tempdir().unwrap();
    // The chaotic-splatting protocol's report is collect of the sweep that adopts the
    // committed runs (README, "As a sweep").
    let cs = tmp.path().join("cs");
    let p = Plan::load(&root.join("paper_repro/chaotic_splatting/sweep.toml")).unwrap();
    ifslab_experiments::sweep::local::adopt(&p, &cs, &results.join("runs")).unwrap();
    let cases = [
        (
            results.join("table3_medium"),
            results.join("table3_medium/report"),
            ReportOptions {
                by: vec![vec!["method".into()]],
                metrics: suite.clone(),
                versus: Some("ours_em_sched".into()),
                ..ReportOptions::default()
            },
            vec!["report.md", "aggregate_method.csv", "paired_method.csv"],
        ),
        (
            results.join("table4_medium"),
            results.join("table4_medium/report"),
            ReportOptions {
                by: vec![vec!["ablation".into()]],
                metrics: suite.clone(),
                versus: Some("ours".into()),
                ..ReportOptions::default()
            },
            vec!["report.md", "aggregate_ablation.csv", "paired_ablation.csv"],
        ),
        (
            results.join("table3_starts"),
            results.join("table3_starts/report"),
            ReportOptions {
                by: vec![vec!["method".into()]],
                metrics: suite.clone(),
                ..ReportOptions::default()
            },
            vec!["report.md", "aggregate_method.csv"],
        ),
        (
            results.join("table4_starts"),
            results.join("table4_starts/report"),
            ReportOptions {
                by: vec![vec!["ablation".into()]],
                metrics: suite,
                versus: Some("ours".into()),
                ..ReportOptions::default()
            },
            vec!["report.md", "aggregate_ablation.csv", "paired_ablation.csv"],
        ),
        (
            cs,
            results.join("sweep_report"),
            ReportOptions {
                by: vec![
                    vec!["group".into(), "target".into(), "strategy".into()],
                    vec!["group".into(), "strategy".into()],
                ],
                metrics: metrics(&["f1", "iou", "psnr", "ssim", "lpips", "seconds"]),
                ..ReportOptions::default()
            },
            vec![
                "report.md",
                "results.csv",
                "aggregate_group_target_strategy.csv",
                "aggregate_group_strategy.csv",
            ],
        ),
        (
            results.join("sweep_em_sierpinski"),
            results.join("sweep_em_sierpinski/report"),
            ReportOptions::default(),
            vec!["report.md", "results.csv", "aggregate_strategy.csv"],
        ),
    ];
    for (k, (dir, committed, opts, files)) in cases.iter().enumerate() {
        let c = collect(dir).unwrap();
        let out = tmp.path().join(format!("report{k}"));
        write_report(&c, &out, opts).unwrap();
        for f in files {
            let want = std::fs::read_to_string(committed.join(f)).unwrap();
            let got = std::fs::read_to_string(out.join(f)).unwrap();
            assert!(
                got == want,
                "{}/{f} is not what collect makes of the committed runs; the first line that \
                 differs:\n{:?}",
                committed.display(),
                got.lines().zip(want.lines()).find(|(a, b)| a != b)
            );
        }
    }
}

#[test]
fn the_ifs_em_sweeps_are_its_committed_results_and_a_rerun_reproduces_one() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let repro = root.join("paper_repro/ifs_em");
    // The convergence and ablation data come from the independent Python sampler; their
    // generating codes are the runs' `truth`, so the ids need the files.
    if !repro.join("data/sampled/random4.csv").is_file() {
        let st = Command::new("bash")
            .arg(repro.join("make_data.sh"))
            .status()
            .expect("bash runs make_data.sh (it needs python3)");
        assert!(st.success(), "make_data.sh failed");
    }
    for (name, n) in [
        ("fig5a", 12),
        ("fig5b", 3),
        ("three_d", 3),
        ("convergence", 14),
        ("ablation", 11),
        ("solid", 2),
        ("fig5b_128", 1),
    ] {
        let p = Plan::load(&repro.join(format!("sweeps/{name}.toml"))).unwrap();
        assert_eq!(p.runs.len(), n, "{name}");
        // The committed folder is this sweep, every run finished: the README's tables are
        // collect's over it.
        let c = collect(&repro.join(format!("results/sweeps/{name}"))).unwrap();
        assert_eq!(c.counts(), (n, 0, 0, 0), "{name}");
        let ids: Vec<&str> = c.rows.iter().map(|r| r.id.as_str()).collect();
        let planned: Vec<&str> = p.runs.iter().map(|r| r.id.as_str()).collect();
        assert_eq!(
            ids, planned,
            "{name}: the committed runs are the sweep's runs"
        );
        assert_eq!(c.unplanned, 0, "{name}");
    }
    // One run again (Fig. 5a, Koch with K = 2: eight seeded EM fits, a few seconds): the
    // same numbers as the committed run, wall time aside.
    let mut p = Plan::load(&repro.join("sweeps/fig5a.toml")).unwrap();
    p.retain(&[
        ("group".into(), "all_positions".into()),
        ("data".into(), "koch-k2".into()),
    ])
    .unwrap();
    assert_eq!(p.runs.len(), 1);
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("f5a");
    let opts = RunnerOptions::new(1, None, Shard::ALL).unwrap();
    let o = run_sweep(&p, &out, &opts, &Silent, &silent).unwrap();
    assert!(o.failures().is_empty(), "{o:?}");
    let id = &p.runs[0].id;
    // The committed run is packed (`runs.jsonl.gz`).
    let pack = Pack::beside(&repro.join("results/sweeps/fig5a/runs")).unwrap();
    let mut committed: serde_json::Value = pack
        .get(id)
        .expect("the run is committed")
        .json("summary.json")
        .unwrap()
        .expect("it has a summary");
    committed.as_object_mut().unwrap().remove("seconds");
    // Every number the committed run reported is the same (later versions may report more).
    assert_reported(&committed, &summary(&run_dir(&out, id)), "summary");
}

/// Every field of `old` is in `new` with the same value, recursively (objects may gain
/// fields).
fn assert_reported(old: &serde_json::Value, new: &serde_json::Value, path: &str) {
    match (old, new) {
        (serde_json::Value::Object(o), serde_json::Value::Object(n)) => {
            for (k, v) in o {
                let Some(w) = n.get(k) else {
                    panic!("{path}.{k} is no longer reported");
                };
                assert_reported(v, w, &format!("{path}.{k}"));
            }
        }
        (serde_json::Value::Array(o), serde_json::Value::Array(n)) => {
            assert_eq!(o.len(), n.len(), "{path}: lengths");
            for (i, (v, w)) in o.iter().zip(n).enumerate() {
                assert_reported(v, w, &format!("{path}[{i}]"));
            }
        }
        _ => assert_eq!(old, new, "{path}"),
    }
}
