//! The `ifslab` command end to end: example configs parse, bad inputs get clear errors and
//! leave nothing half-written, quick runs produce their outputs.

use std::path::Path;
use std::process::Command;

use ifslab_strategies::image::InversionConfig;

fn ifslab(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_ifslab"))
        .args(args)
        .output()
        .expect("the binary runs");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), text)
}

#[test]
fn every_example_config_is_valid() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let cfg =
                InversionConfig::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            if let Some(img) = &cfg.target.image {
                assert!(
                    img.is_file(),
                    "{}: target image {} missing",
                    path.display(),
                    img.display()
                );
            }
            n += 1;
        }
    }
    assert!(n >= 4, "expected the example configs, found {n}");
}

#[test]
fn bad_inputs_get_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let p = |name: &str| tmp.path().join(name).to_string_lossy().into_owned();

    // A corrupt image as target.
    std::fs::write(
        p("corrupt.png"),
        b"\x89PNG\r\n\x1a\nthis is not really a png",
    )
    .unwrap();
    let (ok, msg) = ifslab(&["invert", &p("corrupt.png"), "--iters", "1", "-o", &p("o1")]);
    assert!(!ok && msg.contains("not a readable image"), "{msg}");
    // An all-white target.
    image::GrayImage::from_pixel(40, 40, image::Luma([255]))
        .save(p("white.png"))
        .unwrap();
    let (ok, msg) = ifslab(&["invert", &p("white.png"), "--iters", "1", "-o", &p("o2")]);
    assert!(!ok && msg.contains("all white"), "{msg}");
    // A malformed config names the field.
    std::fs::write(
        p("bad.toml"),
        "iterations = 10\n[target]\ncode = \"fern\"\n[renderer]\nsigma = -2\n",
    )
    .unwrap();
    let (ok, msg) = ifslab(&["run", &p("bad.toml"), "-o", &p("o3")]);
    assert!(!ok && msg.contains("renderer.sigma"), "{msg}");
    assert!(
        !Path::new(&p("o3")).exists(),
        "nothing is written for an invalid config"
    );
    // A non-contractive code file names the map and its singular value.
    std::fs::write(
        p("big.json"),
        r#"{"format": "ifslab-code/1", "dim": 2, "maps": [{"matrix": [[1.5, 0], [0, 0.2]], "offset": [0, 0]}]}"#,
    )
    .unwrap();
    let (ok, msg) = ifslab(&["render", &p("big.json"), "-o", &p("r.png")]);
    assert!(
        !ok && msg.contains("map 0 is not contractive") && msg.contains("1.5"),
        "{msg}"
    );
    // An unknown built-in name lists the known ones.
    let (ok, msg) = ifslab(&["render", "sierpinksi", "-o", &p("r.png")]);
    assert!(!ok && msg.contains("sierpinski"), "{msg}");
    // Resuming a folder without a run.
    let (ok, msg) = ifslab(&["invert", "--resume", &p("nothing")]);
    assert!(!ok && msg.contains("nothing"), "{msg}");
}

#[test]
fn quick_inversion_writes_every_output_and_resumes() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("run");
    let o = out.to_string_lossy().into_owned();
    let args = [
        "invert",
        "sierpinski",
        "--size",
        "32",
        "--iters",
        "6",
        "--trajectories",
        "100",
        "--length",
        "40",
        "--checkpoint-every",
        "3",
        "-o",
        &o,
    ];
    let (ok, msg) = ifslab(&args);
    assert!(ok, "{msg}");
    for f in [
        "code.json",
        "render.png",
        "target.png",
        "zoom_strip.png",
        "loss.png",
        "log.csv",
        "config.toml",
        "summary.json",
        "checkpoint.json",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    ifslab::model::IfsCode::load(out.join("code.json")).unwrap();
    // A second fresh run into the same folder is refused; --resume continues (already done).
    let (ok, msg) = ifslab(&args);
    assert!(!ok && msg.contains("--resume"), "{msg}");
    let (ok, msg) = ifslab(&["invert", "--resume", &o]);
    assert!(ok, "{msg}");
}
