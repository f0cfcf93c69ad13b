//! The flame renderer's and `.flame` format's contracts: the same seed gives the same image
//! whatever the thread count, files go both ways (and what we write loads in flam3-render),
//! bad input is refused with an error that says what and where, and a diverging flame is
//! reported rather than refused.

use std::path::{Path, PathBuf};
use std::process::Command;

use ifslab::Error;
use ifslab::metrics::ssim;
use ifslab::model::flame::{Flame, flames_to_string, parse_flames, read_flames, write_flames};
use ifslab::render::flame::{FlameImage, FlameRenderConfig, render_flame};
use ifslab::render::image_io::load_grey;

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/flame/images")
        .join(name)
}

fn load(name: &str) -> Flame {
    read_flames(&fixture(name)).unwrap().remove(0)
}

fn render_on(threads: usize, flame: &Flame, seed: u64) -> FlameImage {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let cfg = FlameRenderConfig {
        seed,
        ..FlameRenderConfig::default()
    };
    pool.install(|| render_flame(flame, &cfg, None)).unwrap()
}

fn small(mut f: Flame, size: u32, quality: f64) -> Flame {
    f.scale *= size as f64 / f.size[1] as f64;
    f.size = [size, size];
    f.quality = quality;
    f
}

#[test]
fn the_same_seed_gives_the_same_image_on_any_thread_count() {
    // A mixed flame with a random variation (so the trajectories' own generators matter),
    // density estimation and supersampling 2, split into many trajectories.
    for name in ["m03.flame", "v14.flame"] {
        let mut f = small(load(name), 64, 100.0);
        f.supersample = 2;
        let one = render_on(1, &f, 7);
        for threads in [2, 3] {
            let many = render_on(threads, &f, 7);
            assert_eq!(one.pixels, many.pixels, "{name}: 1 vs {threads} threads");
            assert_eq!(one.stats.hits, many.stats.hits);
            assert_eq!(one.stats.badvals, many.stats.badvals);
        }
        let other = render_on(2, &f, 8);
        assert_ne!(
            one.pixels, other.pixels,
            "{name}: another seed, other samples"
        );
        assert!(one.stats.hits > 0);
    }
}

#[test]
fn a_file_read_written_and_read_again_is_identical() {
    for name in ["m00.flame", "m05.flame", "v67.flame", "v98.flame"] {
        let flames = read_flames(&fixture(name)).unwrap();
        let text = flames_to_string(&flames).unwrap();
        let again = parse_flames(&text, Path::new("written.flame")).unwrap();
        assert_eq!(flames, again, "{name}");
        assert_eq!(text, flames_to_string(&again).unwrap());
    }
}

#[test]
fn multi_flame_files_keep_every_flame_and_its_unknown_attributes() {
    let text = r#"<flames name="set">
      <flame name="a" size="32 24" center="0 0" scale="10" my_tool_tag="kept" quality="5">
        <xform weight="1" color="0" linear="1" coefs="0.5 0 0 0.5 0 0" my_xform_flag="on"/>
        <color index="0" rgb="255 0 0"/><color index="255" rgb="0 0 255"/>
      </flame>
      <flame name="b" size="16 16" scale="5" palette="12">
        <xform weight="0.5" color="1" julian="1" julian_power="3" julian_dist="1"
               coefs="0.5 0 0 0.5 0.5 0" post="1 0 0 1 0.1 0"/>
        <xform weight="0.5" color="0" spherical="0.5" linear="0.5" chaos="1 0"
               coefs="0.5 0.1 0 0.5 -0.5 0"/>
        <finalxform color="0" color_speed="0" swirl="1" coefs="1 0 0 1 0 0"/>
      </flame></flames>"#;
    let flames = parse_flames(text, Path::new("set.flame")).unwrap();
    assert_eq!(flames.len(), 2);
    assert_eq!(flames[0].name.as_deref(), Some("a"));
    assert_eq!(flames[0].size, [32, 24]);
    assert!(flames[1].final_xform.is_some());
    assert_eq!(flames[1].xforms[1].chaos, vec![1.0, 0.0]);
    let written = flames_to_string(&flames).unwrap();
    assert!(written.contains(r#"my_tool_tag="kept""#), "{written}");
    assert!(written.contains(r#"my_xform_flag="on""#), "{written}");
    assert_eq!(parse_flames(&written, Path::new("w")).unwrap(), flames);
}

/// What we write loads in flam3-render and renders the same picture. Needs flam3-render
/// (scripts/test.sh installs it); without it the test says so and checks nothing else.
#[test]
fn a_flame_we_write_renders_in_flam3() {
    if Command::new("flam3-render")
        .arg("--version")
        .output()
        .is_err()
    {
        eprintln!(
            "note: flam3-render not installed (apt-get install flam3-utils); skipping the flam3 check"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let f = small(load("m05.flame"), 96, 200.0);
    let path = dir.path().join("ours.flame");
    write_flames(&path, std::slice::from_ref(&f)).unwrap();
    let png = dir.path().join("flam3.png");
    let out = Command::new("flam3-render")
        .env("in", &path)
        .env("out", &png)
        .env("nthreads", "1")
        .env("isaac_seed", "3")
        .env("verbose", "0")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "flam3-render refused our file: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let theirs = load_grey(&png).unwrap();
    let ours = render_on(2, &f, 1);
    assert_eq!((theirs.width, theirs.height), (96, 96));
    let s = ssim(&ours.grey(), &theirs.values, 96, 96).unwrap();
    assert!(
        s > 0.9,
        "SSIM {s} between our render and flam3's of our file"
    );
}

fn parse_err(text: &str) -> String {
    match parse_flames(text, Path::new("bad.flame")) {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    }
}

fn flame_with(xforms: &str, attrs: &str) -> String {
    format!(
        r#"<flames><flame name="f1" size="16 16" scale="4" {attrs}>{xforms}
           <color index="0" rgb="255 255 255"/></flame></flames>"#
    )
}

const LINEAR: &str = r#"<xform weight="1" color="0" linear="1" coefs="0.5 0 0 0.5 0 0"/>"#;

#[test]
fn bad_files_are_refused_naming_what_and_where() {
    let cases: Vec<(String, &[&str])> = vec![
        (
            "<flames><flame><xform".into(),
            &["bad.flame", "line 1", "not well-formed XML"],
        ),
        ("<flames></flames>".into(), &["no <flame> element"]),
        (flame_with("", ""), &["f1", "no <xform>"]),
        (
            flame_with(r#"<xform weight="1" linear="1"/>"#, ""),
            &["f1", "xform 0", "coefs"],
        ),
        (
            flame_with(r#"<xform weight="1" linear="1" coefs="1 0 0 1 0"/>"#, ""),
            &["f1", "xform 0", "coefs"],
        ),
        (
            flame_with(
                r#"<xform weight="1" linear="1" coefs="1 0 nan 1 0 0"/>"#,
                "",
            ),
            &["f1", "xform 0", "coefs"],
        ),
        (flame_with(LINEAR, r#"center="inf 0""#), &["f1", "center"]),
        (
            flame_with(
                &format!(r#"{LINEAR}<xform weight="1" coefs="1 0 0 1 0 0" nosuchvar="0.5"/>"#),
                "",
            ),
            &["nosuchvar", "bad.flame", "f1", "xform 1"],
        ),
        (
            flame_with(
                r#"<xform weight="1" color="0" linear="1" coefs="0.5 0 0 0.5 0 0"/><color index="256" rgb="1 2 3"/>"#,
                "",
            ),
            &["f1", "256"],
        ),
        (
            flame_with(
                r#"<xform weight="1" julian="1" julian_power="x" coefs="1 0 0 1 0 0"/>"#,
                "",
            ),
            &["f1", "xform 0", "julian_power"],
        ),
    ];
    for (text, needles) in cases {
        let msg = parse_err(&text);
        for n in needles {
            assert!(
                msg.to_lowercase().contains(&n.to_lowercase()),
                "error for {text:?} should mention `{n}`: {msg}"
            );
        }
    }
}

#[test]
fn a_degenerate_camera_or_setting_is_refused_before_rendering() {
    let base = parse_flames(&flame_with(LINEAR, ""), Path::new("f.flame")).unwrap()[0].clone();
    let cfg = FlameRenderConfig::default();
    let mut bad: Vec<(Flame, &str)> = Vec::new();
    let mut f = base.clone();
    f.scale = 0.0;
    bad.push((f, "scale"));
    let mut f = base.clone();
    f.size = [0, 16];
    bad.push((f, "size"));
    let mut f = base.clone();
    f.quality = f64::NAN;
    bad.push((f, "quality"));
    let mut f = base.clone();
    f.xforms[0].weight = 0.0;
    bad.push((f, "weight"));
    let mut f = base.clone();
    f.xforms[0].coefs[4] = f64::INFINITY;
    bad.push((f, "coefs"));
    for (f, needle) in bad {
        match render_flame(&f, &cfg, None) {
            Ok(_) => panic!("rendered a flame with a bad {needle}"),
            Err(e) => {
                let msg = e.to_string();
                assert!(msg.contains(needle), "error should name `{needle}`: {msg}");
                assert!(!matches!(e, Error::Io { .. }));
            }
        }
    }
}

#[test]
fn a_diverging_flame_is_reported_and_still_rendered() {
    // An expanding map: every orbit leaves the plane (beyond ±1e10) within a few hundred steps and is
    // restarted from a random point, flam3's bad values.
    let text = flame_with(
        r#"<xform weight="1" color="0" linear="1" coefs="3 0 0 3 0 0"/>
           <xform weight="1" color="1" linear="1" coefs="0.5 0 0 0.5 0.5 0"/>"#,
        r#"quality="20""#,
    );
    let f = parse_flames(&text, Path::new("d.flame")).unwrap().remove(0);
    let img = render_on(2, &f, 1);
    assert!(img.stats.badvals > 0, "{:?}", img.stats);
    assert_eq!(img.pixels.len(), 16 * 16);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("d.png");
    img.save_png(&out, Default::default(), false).unwrap();
    assert!(out.exists());
}
