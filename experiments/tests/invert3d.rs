//! `ifslab invert3d` end to end: 8 turntable views of the Sierpiński tetrahedron at 64²,
//! drawn by the library's multi-view splat, inverted from the visual hull's EM start to a
//! code whose attractor matches the truth's (voxel IoU ≥ 0.8 at 64³ within one voxel), with
//! every output written; and views the command must refuse, with the reason on stderr.

use std::path::Path;
use std::process::{Command, Output};

fn ifslab(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ifslab"))
        .args(args)
        .output()
        .expect("the ifslab binary runs")
}

fn text(o: &Output) -> String {
    format!(
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn render_tetrahedron(views: &Path) {
    let o = ifslab(&[
        "invert3d",
        views.to_str().unwrap(),
        "--render-views",
        "tetrahedron",
        "--views-count",
        "8",
        "--size",
        "64",
    ]);
    assert!(o.status.success(), "{}", text(&o));
}

/// How views drawn by the library's own blurred splat are fitted: from the hull's EM start,
/// at 1×, σ 1.5 → 0.8, 100 trajectories, without the ink guard (the defaults suit crisp
/// views from elsewhere); what `experiments/configs/image3d_tetrahedron.toml` sets.
const OWN_VIEWS: [&str; 10] = [
    "--start",
    "hull",
    "--supersample",
    "1",
    "--sigma-final",
    "0.8",
    "--trajectories",
    "100",
    "--ink",
    "0",
];

#[test]
fn the_tetrahedron_is_recovered_from_eight_views() {
    let tmp = tempfile::tempdir().unwrap();
    let views = tmp.path().join("views");
    let out = tmp.path().join("out");
    render_tetrahedron(&views);
    // Views to score on that the fit never sees: a turntable of 5 (other azimuths).
    let other = tmp.path().join("other");
    let o = ifslab(&[
        "invert3d",
        other.to_str().unwrap(),
        "--render-views",
        "tetrahedron",
        "--views-count",
        "5",
        "--size",
        "64",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = ifslab(
        &[
            "invert3d",
            views.to_str().unwrap(),
            "--maps",
            "4",
            "-o",
            out.to_str().unwrap(),
            "--truth",
            "tetrahedron",
            "--score-views",
            other.to_str().unwrap(),
        ]
        .into_iter()
        .chain(OWN_VIEWS)
        .collect::<Vec<_>>(),
    );
    assert!(o.status.success(), "{}", text(&o));
    println!("{}", text(&o));
    // The views it never saw above the fit's renders: 5 views of 64², two rows.
    let picture = image::open(out.join("other_views.png")).unwrap();
    assert_eq!((picture.width(), picture.height()), (5 * 64, 2 * 64));
    for f in [
        "code.json",
        "baseline.json",
        "points.ply",
        "views.png",
        "turntable.png",
        "summary.json",
        "config.toml",
        "log.csv",
    ] {
        assert!(out.join(f).is_file(), "{f} is missing");
    }
    let code = ifslab::model::IfsCode::load(out.join("code.json")).unwrap();
    assert_eq!(code.dim(), 3);
    assert_eq!(code.maps.len(), 4);
    let ply = std::fs::read_to_string(out.join("points.ply")).unwrap();
    assert!(ply.starts_with("ply\nformat ascii 1.0\n"));
    let n: usize = ply
        .lines()
        .find_map(|l| l.strip_prefix("element vertex "))
        .unwrap()
        .parse()
        .unwrap();
    assert_eq!(ply.lines().count(), n + 8);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let fit = s["fit"]["voxel_iou"].as_f64().unwrap();
    let baseline = s["baseline"]["voxel_iou"].as_f64().unwrap();
    // The trajectories named by the flags, not the 400 per 64² the views' size would give.
    assert_eq!(s["trajectories"], 100, "{s}");
    let unseen = &s["other_views"]["loss"];
    assert!(
        unseen[1].as_f64().unwrap() < unseen[0].as_f64().unwrap(),
        "on views it never saw the fit must beat the baseline: {s}"
    );
    assert!(
        fit >= 0.8,
        "voxel IoU {fit} (baseline {baseline}); summary {s}"
    );
    assert!(
        fit > baseline,
        "the fit must beat the hull + EM baseline: {s}"
    );
    // A second run into the same folder is refused before anything is overwritten.
    let again = ifslab(&[
        "invert3d",
        views.to_str().unwrap(),
        "--maps",
        "4",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!again.status.success());
    assert!(
        text(&again).contains("already holds a run"),
        "{}",
        text(&again)
    );
}

#[test]
fn bad_views_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    // A folder that does not exist.
    let o = ifslab(&["invert3d", tmp.path().join("nowhere").to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("not a folder"), "{}", text(&o));
    // An empty folder: no cameras.
    let o = ifslab(&["invert3d", tmp.path().to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("no cameras"), "{}", text(&o));
    // A view of another size.
    let views = tmp.path().join("views");
    render_tetrahedron(&views);
    ifslab::image::Image::grey(48, 64, vec![1.0; 48 * 64])
        .unwrap()
        .save_png(&views.join("view_003.png"))
        .unwrap();
    let o = ifslab(&["invert3d", views.to_str().unwrap(), "--maps", "4"]);
    assert!(!o.status.success());
    let t = text(&o);
    assert!(t.contains("view_003.png") && t.contains("same size"), "{t}");
    // No map.
    render_tetrahedron(&tmp.path().join("ok"));
    let o = ifslab(&[
        "invert3d",
        tmp.path().join("ok").to_str().unwrap(),
        "--maps",
        "0",
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("maps"), "{}", text(&o));
}

/// The log's rows without their last column (the seconds, which differ between runs).
fn log_rows(dir: &Path) -> Vec<String> {
    std::fs::read_to_string(dir.join("log.csv"))
        .unwrap()
        .lines()
        .map(|l| l.rsplit_once(',').map_or(l, |(head, _)| head).to_owned())
        .collect()
}

/// A run stopped mid-way — killed (SIGKILL) once a checkpoint exists, or stopped by SIGTERM
/// (which checkpoints and says how to continue) — and continued with `--resume` ends with
/// exactly the uninterrupted run's code and log. A fresh run into its folder is refused
/// while it waits to be resumed; `--resume` refuses a folder without a run (creating
/// nothing) and views that changed since the run started.
#[test]
fn a_stopped_run_resumes_to_the_uninterrupted_result() {
    use std::time::{Duration, Instant};
    let tmp = tempfile::tempdir().unwrap();
    let views = tmp.path().join("views");
    render_tetrahedron(&views);
    let args = |out: &Path| -> Vec<String> {
        [
            "invert3d",
            views.to_str().unwrap(),
            "--maps",
            "4",
            "--iters",
            "60",
            "--supersample",
            "1",
            "--sigma-final",
            "0.8",
            "--trajectories",
            "60",
            "--ink",
            "0",
            "--checkpoint-every",
            "3",
            "--truth",
            "tetrahedron",
            "-o",
            out.to_str().unwrap(),
        ]
        .map(String::from)
        .to_vec()
    };
    let run = |a: &[String]| ifslab(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let whole = tmp.path().join("whole");
    let o = run(&args(&whole));
    assert!(o.status.success(), "{}", text(&o));

    for (mode, signal) in [("killed", None), ("terminated", Some("-TERM"))] {
        let out = tmp.path().join(mode);
        let mut child = Command::new(env!("CARGO_BIN_EXE_ifslab"))
            .args(args(&out))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        let ckpt = out.join("checkpoint.json");
        let t0 = Instant::now();
        while !ckpt.exists() {
            assert!(t0.elapsed() < Duration::from_secs(120), "no checkpoint");
            std::thread::sleep(Duration::from_millis(2));
        }
        match signal {
            None => {
                child.kill().unwrap();
                child.wait().unwrap();
            }
            Some(sig) => {
                let pid = child.id().to_string();
                let sent = Command::new("kill").args([sig, &pid]).status().unwrap();
                assert!(sent.success());
                let o = child.wait_with_output().unwrap();
                let err = String::from_utf8_lossy(&o.stderr);
                assert!(
                    !o.status.success(),
                    "{mode}: the run was not stopped: {err}"
                );
                assert!(
                    err.contains("interrupted after iteration")
                        && err.contains(&format!("invert3d --resume {}", out.display())),
                    "{err}"
                );
            }
        }
        assert!(
            !out.join("summary.json").exists(),
            "{mode}: the run finished before it was stopped: nothing would be resumed"
        );
        // A fresh run into the stopped run's folder is refused, naming --resume.
        let o = run(&args(&out));
        let t = text(&o);
        assert!(
            !o.status.success() && t.contains("already holds a run") && t.contains("--resume"),
            "{t}"
        );
        let o = ifslab(&["invert3d", "--resume", out.to_str().unwrap()]);
        assert!(o.status.success(), "{mode}: {}", text(&o));
        assert_eq!(
            std::fs::read_to_string(out.join("code.json")).unwrap(),
            std::fs::read_to_string(whole.join("code.json")).unwrap(),
            "{mode}: resumed ≠ uninterrupted"
        );
        assert_eq!(log_rows(&out), log_rows(&whole), "{mode}: the logs differ");
        assert_eq!(log_rows(&out).len(), 61, "a header and 60 iterations");
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap())
                .unwrap();
        assert_eq!(s["iterations"], 60);
        assert!(s["fit"]["voxel_iou"].as_f64().unwrap() > 0.0, "{s}");
    }

    // Nothing to resume: a folder that does not exist (and is not created) or holds no run.
    let nothing = tmp.path().join("nothing");
    let o = ifslab(&["invert3d", "--resume", nothing.to_str().unwrap()]);
    let t = text(&o);
    assert!(
        !o.status.success() && t.contains("holds no invert3d run to resume"),
        "{t}"
    );
    assert!(!nothing.exists());
    let o = ifslab(&["invert3d", "--resume", views.to_str().unwrap()]);
    assert!(!o.status.success(), "{}", text(&o));
    // Views that changed since the run started are refused (one picture replaced by
    // another's).
    std::fs::copy(views.join("view_003.png"), views.join("view_002.png")).unwrap();
    let o = ifslab(&["invert3d", "--resume", whole.to_str().unwrap()]);
    let t = text(&o);
    assert!(
        !o.status.success() && t.contains("changed since the run"),
        "{t}"
    );
}

/// `ifslab run` of a `problem = "image3d"` config (the shipped example) and `ifslab
/// invert3d` with the same settings as flags are one run: the same code, the same log. The
/// config's folder resumes with `ifslab run --resume`; a folder made before configs named
/// their views (a `config.toml` of the fit's keys alone, the inputs in `invert3d.json`)
/// still resumes with `invert3d --resume`, to the same code.
#[test]
fn a_config_runs_what_the_flags_run_and_old_folders_still_resume() {
    let tmp = tempfile::tempdir().unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let config = root.join("experiments/configs/image3d_tetrahedron.toml");
    let views = root.join("data/views/tetrahedron");
    let by_config = tmp.path().join("config");
    let by_flags = tmp.path().join("flags");
    let o = ifslab(&[
        "run",
        config.to_str().unwrap(),
        "--set",
        "iterations=24",
        "-o",
        by_config.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("voxel IoU baseline"), "{}", text(&o));
    let o = ifslab(
        &[
            "invert3d",
            views.to_str().unwrap(),
            "--maps",
            "4",
            "--iters",
            "24",
            "--truth",
            "tetrahedron",
            "-o",
            by_flags.to_str().unwrap(),
        ]
        .into_iter()
        .chain(OWN_VIEWS)
        .collect::<Vec<_>>(),
    );
    assert!(o.status.success(), "{}", text(&o));
    let read = |dir: &Path, f: &str| std::fs::read_to_string(dir.join(f)).unwrap();
    assert_eq!(read(&by_config, "code.json"), read(&by_flags, "code.json"));
    assert_eq!(log_rows(&by_config), log_rows(&by_flags));
    let cfg: toml::Table = read(&by_flags, "config.toml").parse().unwrap();
    assert_eq!(cfg["problem"].as_str(), Some("image3d"));
    assert!(cfg["views"].as_str().unwrap().ends_with("tetrahedron"));

    // The config's folder, its outputs removed, resumes through `ifslab run --resume` —
    // with its own config, not another.
    let code = read(&by_config, "code.json");
    std::fs::remove_file(by_config.join("code.json")).unwrap();
    let o = ifslab(&[
        "run",
        config.to_str().unwrap(),
        "--set",
        "iterations=25",
        "--resume",
        "-o",
        by_config.to_str().unwrap(),
    ]);
    assert!(
        !o.status.success() && text(&o).contains("holds a run of another config"),
        "{}",
        text(&o)
    );
    let o = ifslab(&[
        "run",
        config.to_str().unwrap(),
        "--set",
        "iterations=24",
        "--resume",
        "-o",
        by_config.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(read(&by_config, "code.json"), code);

    // The same folder as the command wrote them before: the inputs' keys out of the config
    // and in `invert3d.json` beside the views' fingerprint.
    let mut old = cfg.clone();
    let mut inputs: serde_json::Value =
        serde_json::from_str(&read(&by_flags, "invert3d.json")).unwrap();
    for k in ["views", "truth"] {
        inputs[k] = old[k].as_str().unwrap().into();
    }
    for k in ["problem", "views", "truth", "score_views"] {
        old.remove(k);
    }
    std::fs::write(by_flags.join("config.toml"), toml::to_string(&old).unwrap()).unwrap();
    std::fs::write(by_flags.join("invert3d.json"), inputs.to_string()).unwrap();
    std::fs::remove_file(by_flags.join("code.json")).unwrap();
    let o = ifslab(&["invert3d", "--resume", by_flags.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert_eq!(read(&by_flags, "code.json"), code);
}
