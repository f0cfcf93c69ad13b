//! A map family that is not affine goes through the run call end to end: the `flame`
//! family (flam3's `linear` and `sinusoidal` variations) inverts a picture through
//! [`RunConfig::run`], and its result — a fit file, no affine code file — draws the run's
//! render, zoom strip and truth again, packed and unpacked like any run; the IoU polish,
//! which moves affine maps, is refused by the config's check, before a folder is made.

use ifslab_experiments::progress::Silent;
use ifslab_experiments::runs::{RunConfig, redraw_pictures};
use ifslab_experiments::sweep::pack::{DEFAULT_LOG_COLUMNS, pack, unpack};
use ifslab_strategies::problems::image::{FIT_FILE, FitFile};

/// Sierpiński's triangle at 32², three flame maps from the EM start, 40 Adam iterations.
const CONFIG: &str = r#"
seed = 2
iterations = 40
checkpoint_every = 20

[target]
code = "sierpinski"
size = 32

[model]
family = "flame"
maps = 3
init = "em"

[generator]
trajectories = 200
length = 60

[loss]
lpips_weight = 0.0

[strategy]
kind = "adam"
"#;

#[test]
fn a_family_that_is_not_affine_writes_and_redraws_its_own_result() {
    let tmp = tempfile::tempdir().unwrap();
    let runs = tmp.path().join("runs");
    let dir = runs.join("flame");
    let cfg = RunConfig::from_toml(CONFIG, &tmp.path().join("flame.toml")).unwrap();
    let report = cfg.run(&dir, false, Box::new(Silent)).unwrap();
    let s = &report.summary;
    assert_eq!(s["iterations"], 40, "{s}");
    // The recovered maps draw Sierpiński's triangle (the evaluation render against the
    // true code's).
    assert!(s["iou"].as_f64().unwrap() > 0.4, "{s}");

    // Its result is θ with the model that decodes it, and no affine code file.
    assert!(!dir.join("code.json").exists());
    let fit = FitFile::load(&dir.join(FIT_FILE)).unwrap();
    assert_eq!(fit.model.family, "flame");
    assert_eq!(fit.theta.len(), 3 * 8);
    assert_eq!(fit.seed(), Some(2));
    assert!(fit.framing.is_some());
    let recovered = fit.recovered().unwrap();
    assert!(recovered.affine().is_none() && recovered.contractive());
    assert_eq!(recovered.n_maps(), 3);

    let pictures = ["render.png", "zoom_strip.png", "truth.png", "target.png"];
    let drawn: Vec<Vec<u8>> = pictures
        .iter()
        .map(|p| std::fs::read(dir.join(p)).unwrap_or_else(|e| panic!("{p}: {e}")))
        .collect();

    // Packed (the folder removed), unpacked, drawn again: the same pictures, bit for bit.
    let keep: Vec<String> = DEFAULT_LOG_COLUMNS.iter().map(|c| c.to_string()).collect();
    let packed = pack(&runs, &keep, true).unwrap();
    assert_eq!((packed.runs, packed.removed), (1, 1));
    assert!(!dir.exists());
    unpack(&runs, &["flame".to_string()]).unwrap();
    assert!(dir.join(FIT_FILE).is_file() && !dir.join("render.png").exists());
    redraw_pictures(&dir).unwrap();
    for (p, before) in pictures.iter().zip(&drawn) {
        assert!(
            std::fs::read(dir.join(p)).unwrap() == *before,
            "{p} is not the run's"
        );
    }
}

#[test]
fn the_iou_polish_is_refused_for_maps_that_are_not_affine_when_the_config_is_read() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let text = CONFIG.replace("init = \"em\"", "init = \"em\"\npolish = 2");
    // Refused where the config is read: no run, no folder.
    let e = format!(
        "{:#}",
        RunConfig::from_toml(&text, &tmp.path().join("flame.toml")).unwrap_err()
    );
    assert!(e.contains("polish") && e.contains("flame"), "{e}");
    assert!(
        !dir.join("log.csv").exists(),
        "refused before any iteration"
    );
    assert!(
        !dir.exists(),
        "refused by the config's check: no folder to clear"
    );
}
