//! `ifslab run` on point-cloud (EM) and texture configs end to end: the run folder's
//! contents and sane summaries, a points run killed mid-way and resumed equal to the
//! uninterrupted one, and bad configs refused with the field named.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{ifslab_in, ifslab_with};
use ifslab_experiments::runs::RunConfig;

fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json"))
        .unwrap_or_else(|e| panic!("{}/summary.json: {e}", dir.display()));
    serde_json::from_str(&text).unwrap()
}

/// A small EM problem: 3000 points of the Sierpiński triangle, depth 4.
const SMALL_POINTS: &str = "problem = \"points\"\ndata = \"ifs:sierpinski\"\npoints = 3000\n\
    k = 3\ndepth = 4\npool = 3\niterations = 60\nseed = 1\ntruth = \"sierpinski\"\n\
    render_points = 100000\n";

#[test]
fn a_points_config_runs_end_to_end() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tmp.path().join("points.toml");
    std::fs::write(&cfg, format!("{SMALL_POINTS}runs = 2\n")).unwrap();
    let (ok, msg) = ifslab_in(tmp.path(), &["run", "points.toml", "-o", "out"]);
    assert!(ok, "{msg}");
    let out = tmp.path().join("out");
    for f in [
        "config.toml",
        "summary.json",
        "report.json",
        "code.json",
        "history.csv",
        "loglik.png",
        "scatter.png",
        "render.png",
    ] {
        assert!(out.join(f).is_file(), "{f} missing: {msg}");
    }
    assert!(
        !out.join("fits").exists(),
        "the checkpoints of a finished run are removed"
    );
    // The messages a person (or a script) reads are lines on stderr.
    assert!(msg.contains("run 1: held-out"), "{msg}");
    let s = summary(&out);
    assert_eq!(s["fits"], 2);
    assert_eq!(s["points"][0], 3000);
    let best = &s["best"];
    assert_eq!(best["converged"], true, "{s}");
    assert!(best["truth_agreement"].as_f64().unwrap() >= 0.9, "{s}");
    // The IFS model explains its own attractor far better than Gaussian mixtures with as
    // many parameters.
    let ll = best["heldout_log_likelihood"].as_f64().unwrap();
    let gmm = best["best_gmm_heldout_log_likelihood"].as_f64().unwrap();
    assert!(ll > gmm + 0.3, "EM {ll} vs GMM {gmm}");
    // Of the two runs the kept one is the attractor closest to the cloud, both ways.
    assert_eq!(best["kept_by"], "closeness", "{s}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    let chamfer = |r: &serde_json::Value| {
        r["closeness"]["data_to_fit"].as_f64().unwrap()
            + r["closeness"]["fit_to_data"].as_f64().unwrap()
    };
    let runs = report["em"]["runs"].as_array().unwrap();
    let closest = (0..runs.len())
        .min_by(|&a, &b| chamfer(&runs[a]).total_cmp(&chamfer(&runs[b])))
        .unwrap();
    assert_eq!(best["run"], closest, "{report}");
    // The code is the best run's, and the written config is the same run anywhere.
    let code = ifslab::model::IfsCode::load(out.join("code.json")).unwrap();
    assert_eq!(code.maps.len(), 3);
    let written = std::fs::read_to_string(out.join("config.toml")).unwrap();
    assert!(written.starts_with("problem = \"points\""), "{written}");
    assert!(written.contains("update = \"all-positions\""), "{written}");
    assert!(written.contains("keep = \"closeness\""), "{written}");
    let back = RunConfig::load(&out.join("config.toml")).unwrap();
    let orig = RunConfig::load(&cfg).unwrap();
    assert_eq!(back.to_table().unwrap(), orig.to_table().unwrap());
}

#[test]
fn a_four_dimensional_cloud_keeps_its_run_by_likelihood() {
    // The closeness is measured in up to three dimensions: 4-D data fall back to the
    // likelihood, and the run says so.
    let tmp = tempfile::tempdir().unwrap();
    let rows: String = (0..600)
        .map(|i| {
            let t = i as f64;
            format!(
                "{},{},{},{}\n",
                (t * 0.37).sin(),
                (t * 0.61).cos(),
                (t * 0.13).fract(),
                (t * 0.29).sin() * 0.5
            )
        })
        .collect();
    std::fs::write(tmp.path().join("cloud.csv"), rows).unwrap();
    let (ok, msg) = ifslab_in(
        tmp.path(),
        &[
            "fit-points",
            "cloud.csv",
            "--k",
            "2",
            "--depth",
            "2",
            "--pool",
            "2",
            "--iters",
            "20",
            "--runs",
            "2",
            "-o",
            "out",
        ],
    );
    assert!(ok, "{msg}");
    let s = summary(&tmp.path().join("out"));
    assert_eq!(s["best"]["kept_by"], "likelihood", "{s}");
    assert!(s["best"]["closeness"].is_null(), "{s}");
}

/// Crops a `side`² grey texture out of the shipped brick texture.
fn small_texture(dir: &Path, side: u32) -> PathBuf {
    let brick = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/textures/brick.png");
    let img = image::open(brick).unwrap().to_luma8();
    let crop = image::imageops::crop_imm(&img, 100, 100, side, side).to_image();
    let p = dir.join("small.png");
    crop.save(&p).unwrap();
    p
}

#[test]
fn a_texture_config_runs_end_to_end_with_its_baseline() {
    let tmp = tempfile::tempdir().unwrap();
    small_texture(tmp.path(), 64);
    let write = |name: &str, extra: &str| {
        std::fs::write(
            tmp.path().join(name),
            format!("problem = \"texture\"\nsource = \"small.png\"\nfactor = 4\n{extra}"),
        )
        .unwrap();
    };
    write(
        "fractal.toml",
        "preset = \"paper\"\nmatching = \"mean-removed\"\n",
    );
    write("bicubic.toml", "filter = \"bicubic\"\n");
    // Run from another folder: the config's relative source is read from its own folder.
    let (ok, msg) = ifslab_in(
        Path::new("/"),
        &[
            "run",
            tmp.path().join("fractal.toml").to_str().unwrap(),
            "-o",
            tmp.path().join("fractal").to_str().unwrap(),
        ],
    );
    assert!(ok, "{msg}");
    let (ok, msg2) = ifslab_in(tmp.path(), &["run", "bicubic.toml", "-o", "bicubic"]);
    assert!(ok, "{msg2}");

    let f = tmp.path().join("fractal");
    for p in [
        "config.toml",
        "summary.json",
        "upsampled.png",
        "code/code.json",
        "code/reduced.png",
        "code/coords.png",
        "code/offsets.png",
    ] {
        assert!(f.join(p).is_file(), "{p} missing: {msg}");
    }
    let up = image::open(f.join("upsampled.png")).unwrap();
    assert_eq!((up.width(), up.height()), (256, 256));
    let s = summary(&f);
    assert_eq!(s["output_size"], serde_json::json!([256, 256]));
    assert_eq!(s["method"], "fractal (paper preset)");
    // The 1× reconstruction from R is close to the source (the paper's Table I measure:
    // 23–34 dB on its textures), the packed 8-bit code no more than a little worse.
    let p1 = s["psnr_1x"].as_f64().unwrap();
    let p1_packed = s["psnr_1x_packed"].as_f64().unwrap();
    assert!(p1 > 25.0 && p1_packed > p1 - 1.0, "{s}");
    let ho = s["psnr_holdout_2x"].as_f64().unwrap();
    assert!(ho > 15.0 && ho < p1, "{s}");
    // An override is kept, the rest of the preset written out.
    let written = std::fs::read_to_string(f.join("config.toml")).unwrap();
    assert!(written.starts_with("problem = \"texture\""), "{written}");
    assert!(
        written.contains("matching = \"mean-removed\"") && written.contains("grid = \"even\""),
        "{written}"
    );

    let b = summary(&tmp.path().join("bicubic"));
    assert_eq!(b["method"], "bicubic");
    assert!(b["psnr_1x"].is_null(), "{b}");
    assert!(b["psnr_holdout_2x"].as_f64().unwrap() > 15.0, "{b}");
}

/// Starts `args` in `dir`, kills it (SIGKILL) as soon as `first` exists, and checks that
/// the run was interrupted: no summary yet.
fn kill_once_written(dir: &Path, args: &[&str], first: impl Fn() -> bool, out: &Path) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ifslab"))
        .current_dir(dir)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !first() && t0.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(2));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(first(), "the run never wrote a checkpoint");
    assert!(
        !out.join("summary.json").exists(),
        "the run finished before it was killed: nothing would be resumed"
    );
}

/// Finished fits checkpointed in run folder `dir` (not the temporary files of a write).
fn fit_files(dir: &Path) -> usize {
    std::fs::read_dir(dir.join("fits")).map_or(0, |d| {
        d.filter(|e| {
            let name = e.as_ref().unwrap().file_name();
            let name = name.to_string_lossy();
            name.ends_with(".json") && !name.starts_with('.')
        })
        .count()
    })
}

/// A sweep killed mid-way (on all threads) and resumed from another folder ends with the
/// result of an uninterrupted run on one thread.
#[test]
fn a_killed_pool_sweep_resumes_to_the_uninterrupted_result() {
    let tmp = tempfile::tempdir().unwrap();
    let work = tmp.path().join("work");
    std::fs::create_dir_all(&work).unwrap();
    std::fs::write(
        work.join("sweep.toml"),
        format!("{SMALL_POINTS}sweep_pool = [1, 3]\nrepeats = 6\n")
            .replace("depth = 4", "depth = 5")
            .replace("iterations = 60", "iterations = 100"),
    )
    .unwrap();
    // The uninterrupted run on one thread: the sweep's fits run in parallel, and the merged
    // result must not depend on how many threads ran them, or in which order they ended.
    let (ok, msg) = ifslab_with(
        &work,
        &["run", "sweep.toml", "-o", "whole"],
        &[("RAYON_NUM_THREADS", "1")],
    );
    assert!(ok, "{msg}");

    let run = work.join("run");
    kill_once_written(
        &work,
        &["run", "sweep.toml", "-o", "run"],
        || fit_files(&run) > 0,
        &run,
    );
    let finished = fit_files(&run);
    assert!(finished < 12, "all 12 fits were done before the kill");
    // A fresh run does not overwrite an unfinished one.
    let (ok, msg) = ifslab_in(&work, &["run", "sweep.toml", "-o", "run"]);
    assert!(!ok && msg.contains("--resume"), "{msg}");
    // Resumed from another folder, by the run folder's own config.
    let (ok, msg) = ifslab_in(tmp.path(), &["fit-points", "--resume", "work/run"]);
    assert!(ok, "{msg}");

    let csv = |d: &str| std::fs::read_to_string(work.join(d).join("pool_sweep.csv")).unwrap();
    assert_eq!(csv("run"), csv("whole"), "resumed ≠ uninterrupted");
    let (s, w) = (summary(&run), summary(&work.join("whole")));
    assert_eq!(s["sweep"], w["sweep"]);
    assert_eq!(s["fits"], 12);
    assert!(
        s["resumed_fits"].as_u64().unwrap() >= finished as u64,
        "{s}"
    );
    assert_eq!(w["resumed_fits"], 0);
    assert!(!run.join("fits").exists());
}

#[test]
fn a_killed_multi_run_fit_resumes_to_the_uninterrupted_result() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = format!("{SMALL_POINTS}runs = 4\n").replace("iterations = 60", "iterations = 200");
    std::fs::write(tmp.path().join("runs.toml"), cfg).unwrap();
    let (ok, msg) = ifslab_in(tmp.path(), &["run", "runs.toml", "-o", "whole"]);
    assert!(ok, "{msg}");
    let run = tmp.path().join("run");
    kill_once_written(
        tmp.path(),
        &["run", "runs.toml", "-o", "run"],
        || fit_files(&run) > 0,
        &run,
    );
    let (ok, msg) = ifslab_in(tmp.path(), &["run", "runs.toml", "-o", "run", "--resume"]);
    assert!(ok, "{msg}");
    let read = |d: &str, f: &str| std::fs::read_to_string(tmp.path().join(d).join(f)).unwrap();
    assert_eq!(read("run", "code.json"), read("whole", "code.json"));
    assert_eq!(read("run", "history.csv"), read("whole", "history.csv"));
    let report = |d: &str| {
        let mut r: serde_json::Value = serde_json::from_str(&read(d, "report.json")).unwrap();
        r.as_object_mut().unwrap().remove("seconds");
        for run in r["em"]["runs"].as_array_mut().unwrap() {
            run.as_object_mut().unwrap().remove("seconds");
        }
        r
    };
    assert_eq!(report("run"), report("whole"));
    assert!(summary(&run)["resumed_fits"].as_u64().unwrap() >= 1);
}

#[test]
fn bad_points_and_texture_configs_name_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    small_texture(tmp.path(), 16);
    let cases: &[(&str, &str)] = &[
        ("problem = \"points\"\nk = 3\n", "`data` is missing"),
        (
            "problem = \"points\"\ndata = \"ifs:sierpinski\"\nk = 0\n",
            "k",
        ),
        (
            "problem = \"points\"\ndata = \"ifs:sierpinski\"\nheldout = 1.5\n",
            "`heldout`",
        ),
        (
            "problem = \"points\"\ndata = \"ifs:sierpinski\"\nbogus = 1\n",
            "bogus",
        ),
        (
            "problem = \"points\"\ndata = \"ifs:sierpinski\"\nsweep_pool = [1, 0]\n",
            "`sweep_pool`",
        ),
        (
            "problem = \"points\"\ndata = \"ifs:sierpinski\"\npaper = true\nupsate = \"outermost\"\n",
            "upsate",
        ),
        (
            "problem = \"points\"\ndata = \"ifs:sierpinski\"\npaper = true\nupdate = \"all-positions\"\n",
            "`update` conflicts with `paper = true`",
        ),
        (
            "problem = \"points\"\ndata = \"ifs:sierpinski\"\npaper = true\nwords = true\n",
            "`words` conflicts with `paper = true`",
        ),
        (
            "problem = \"points\"\ndata = \"missing.csv\"\n",
            "missing.csv",
        ),
        ("problem = \"texture\"\nfactor = 8\n", "`source` is missing"),
        (
            "problem = \"texture\"\nsource = \"small.png\"\nfactor = 3\n",
            "`factor`",
        ),
        (
            "problem = \"texture\"\nsource = \"small.png\"\nmax_candidates = 0\n",
            "max_candidates",
        ),
        (
            "problem = \"texture\"\nsource = \"small.png\"\nfilter = \"sinc\"\n",
            "filter",
        ),
        (
            "problem = \"texture\"\nsource = \"small.png\"\ngrid = \"all\"\ncoord_storage = \"half-signed\"\n",
            "coord_storage",
        ),
    ];
    for (i, (text, want)) in cases.iter().enumerate() {
        let cfg = tmp.path().join(format!("bad{i}.toml"));
        std::fs::write(&cfg, text).unwrap();
        let out = tmp.path().join(format!("o{i}"));
        let (ok, msg) = ifslab_in(
            tmp.path(),
            &["run", cfg.to_str().unwrap(), "-o", out.to_str().unwrap()],
        );
        assert!(
            !ok && msg.contains(want),
            "{text}: wanted `{want}` in: {msg}"
        );
        assert!(!msg.contains("panicked"), "{msg}");
        assert!(
            !out.join("summary.json").exists(),
            "{text}: an invalid config ran"
        );
    }
    // The command line names its flags.
    let (ok, msg) = ifslab_in(
        tmp.path(),
        &["fit-points", "ifs:sierpinski", "--runs", "0", "-o", "x"],
    );
    assert!(!ok && msg.contains("--runs"), "{msg}");
}

fn argv(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

/// The texture reproduction saves each finished texture; killed after the first and resumed,
/// it does not redo that texture (its saved timings are kept) and ends with the same tables.
#[test]
fn a_killed_texture_repro_resumes_after_its_finished_textures() {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("data");
    std::fs::create_dir_all(&data).unwrap();
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/textures");
    for name in ["brick", "grass", "gravel"] {
        let img = image::open(shipped.join(format!("{name}.png")))
            .unwrap()
            .to_luma8();
        image::imageops::crop_imm(&img, 64, 64, 128, 128)
            .to_image()
            .save(data.join(format!("{name}.png")))
            .unwrap();
    }
    let args = |out: &str| -> Vec<String> {
        [
            "texture",
            "repro",
            "--data",
            "data",
            "--textures",
            "brick,grass,gravel",
            "--tables-only",
            "--skip-ablation",
            "--out",
            out,
        ]
        .map(String::from)
        .to_vec()
    };
    let (ok, msg) = ifslab_in(tmp.path(), &argv(&args("whole")));
    assert!(ok, "{msg}");

    let out = tmp.path().join("run");
    let first = out.join("partial/brick.json");
    kill_once_written(tmp.path(), &argv(&args("run")), || first.is_file(), &out);
    assert!(
        !out.join("tables.md").exists(),
        "the repro finished before it was killed"
    );
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&first).unwrap()).unwrap();
    let mut resume = args("run");
    resume.push("--resume".into());
    let (ok, msg) = ifslab_in(tmp.path(), &argv(&resume));
    assert!(ok, "{msg}");
    assert!(msg.contains("== brick: done before"), "{msg}");
    assert!(!out.join("partial").exists());

    let results = |d: &str| -> serde_json::Value {
        serde_json::from_str(
            &std::fs::read_to_string(tmp.path().join(d).join("results.json")).unwrap(),
        )
        .unwrap()
    };
    let (r, w) = (results("run"), results("whole"));
    // Brick comes from the checkpoint: its measured times are the killed run's.
    assert_eq!(r["brick"]["codes"], saved["rows"]);
    // Every texture's scores equal the uninterrupted run's (times aside).
    for name in ["brick", "grass", "gravel"] {
        let scores = |v: &serde_json::Value| -> Vec<(f64, f64, f64)> {
            v[name]["codes"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| {
                    (
                        c["psnr_1x"].as_f64().unwrap(),
                        c["psnr_1x_packed"].as_f64().unwrap(),
                        c["psnr_holdout_2x"].as_f64().unwrap(),
                    )
                })
                .collect()
        };
        assert_eq!(scores(&r), scores(&w), "{name}");
        assert_eq!(r[name]["baselines"], w[name]["baselines"], "{name}");
    }
}
