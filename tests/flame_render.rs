//! The flame renderer's and `.flame` format's contracts: the same seed gives the same image
//! whatever the thread count, files go both ways (and what we write loads in flam3-render),
//! bad input is refused with an error that says what and where, and a diverging flame is
//! reported rather than refused.

use std::path::{Path, PathBuf};
use std::process::Command;

use ifslab::Error;
use ifslab::isa::Isa;
use ifslab::metrics::ssim;
use ifslab::model::flame::{Flame, flames_to_string, parse_flames, read_flames, write_flames};
use ifslab::render::flame::{FlameImage, FlameRenderConfig, render_flame, render_flame_with_isa};
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
fn instruction_sets_give_the_same_image() {
    // The chaos game's AVX2+FMA copy (variations through their FMA-compiled formulas, the
    // trigonometry inlined with single-instruction multiply–adds) against the portable one
    // (each multiply–add a call to the runtime's exact `fma`): the same bits. Mixed
    // trigonometric flames, a random variation, pre_blur, a final transform.
    let cfg = FlameRenderConfig {
        seed: 3,
        ..FlameRenderConfig::default()
    };
    for name in [
        "m05.flame",
        "m03.flame",
        "v14.flame",
        "v67.flame",
        "m07.flame",
    ] {
        let f = small(load(name), 48, 40.0);
        let portable = render_flame_with_isa(&f, &cfg, None, Isa::Portable).unwrap();
        if !Isa::Fma.is_available() {
            // Without AVX2+FMA the fast copy must refuse clearly rather than run.
            let e = render_flame_with_isa(&f, &cfg, None, Isa::Fma)
                .unwrap_err()
                .to_string();
            assert!(e.contains("AVX2"), "{e}");
            continue;
        }
        let fma = render_flame_with_isa(&f, &cfg, None, Isa::Fma).unwrap();
        assert!(portable.stats.hits > 0, "{name}: nothing plotted");
        assert_eq!(portable.stats.hits, fma.stats.hits, "{name}");
        assert_eq!(portable.stats.badvals, fma.stats.badvals, "{name}");
        let bits = |img: &FlameImage| -> Vec<u32> {
            img.pixels.iter().flatten().map(|v| v.to_bits()).collect()
        };
        assert_eq!(bits(&portable), bits(&fma), "{name}");
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
      <flame name="b" size="16 16" scale="5">
        <xform weight="0.5" color="1" julian="1" julian_power="3" julian_dist="1"
               coefs="0.5 0 0 0.5 0.5 0" post="1 0 0 1 0.1 0"/>
        <xform weight="0.5" color="0" spherical="0.5" linear="0.5" chaos="1 0"
               coefs="0.5 0.1 0 0.5 -0.5 0"/>
        <finalxform color="0" color_speed="0" swirl="1" coefs="1 0 0 1 0 0"/>
        <color index="0" rgb="1 2 3"/>
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

/// What we write loads in flam3-render and renders the same picture. Needs flam3-render,
/// which scripts/test.sh (CI) installs: without it this test fails rather than pass unchecked.
#[test]
fn a_flame_we_write_renders_in_flam3() {
    assert!(
        Command::new("flam3-render")
            .arg("--version")
            .output()
            .is_ok(),
        "flam3-render is not installed: `apt-get install flam3-utils flam3-palette` \
         (scripts/test.sh does it); this test checks our .flame files against it"
    );
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
    let s = ssim(&ours.grey().values, &theirs.values, 96, 96).unwrap();
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

/// 256 colours as Apophysis writes them: `<palette count="256" format="RGB">` with six hex
/// digits per colour.
fn hex_palette() -> String {
    let mut s = String::new();
    for i in 0..256 {
        if i % 8 == 0 {
            s.push_str("\n      ");
        }
        s.push_str(&format!("{:02X}{:02X}{:02X}", i, 255 - i, (i * 7) % 256));
    }
    s
}

#[test]
fn apophysis_and_jwildfire_files_load_with_their_extras_kept() {
    let apo = format!(
        r#"<Flames name="apo">
<flame name="Apo-1" version="Apophysis 2.09" size="64 48" center="0.1 -0.2" scale="20"
       angle="0" rotate="-0" zoom="0" oversample="2" filter="0.2" quality="3" batches="1"
       background="0 0 0" brightness="4" gamma="4" vibrancy="1" hue="0" estimator_radius="9"
       estimator_minimum="0" estimator_curve="0.4" enable_de="0" gamma_threshold="0.04">
   <xform weight="0.5" color="0" symmetry="0" linear="0.5" julia="0.5" chaos="1 0.5"
          coefs="0.5 0 0 0.5 0 0" post="1 0 0 1 0.2 0" opacity="1" var_color="1"/>
   <xform weight="0.5" color="1" symmetry="0.5" pdj="1" pdj_a="1.1" pdj_b="-2" pdj_c="0.3"
          pdj_d="2.4" coefs="0.6 0.1 -0.1 0.6 0.3 0.1" var_color="1"/>
   <finalxform color="0" symmetry="1" spherical="1" coefs="1 0 0 1 0 0"/>
   <palette count="256" format="RGB">{}
   </palette>
</flame>
</Flames>"#,
        hex_palette()
    );
    let f = parse_flames(&apo, Path::new("apo.flame"))
        .unwrap()
        .remove(0);
    assert_eq!(f.supersample, 2);
    assert_eq!(
        f.xforms[1].color_speed, 0.25,
        "symmetry s means colour speed (1 − s)/2"
    );
    assert_eq!(f.xforms[1].variations[0].param("pdj_b"), Some(-2.0));
    assert_eq!(f.palette.colors[10], [10.0, 245.0, 70.0, 255.0]);
    assert!(f.final_xform.is_some());
    let text = flames_to_string(std::slice::from_ref(&f)).unwrap();
    for kept in [r#"angle="0""#, r#"enable_de="0""#, r#"var_color="1""#] {
        assert!(text.contains(kept), "{kept} lost: {text}");
    }
    assert_eq!(parse_flames(&text, Path::new("w")).unwrap()[0], f);
    assert!(render_on(1, &f, 1).stats.hits > 0);

    let jwf = r#"<flame name="JWF" version="JWildfire 7.50" size="40 40" center="0 0" scale="12"
       rotate="0" filter="0.75" filter_kernel="GAUSSIAN" quality="4" background="0 0 0"
       bg_transparency="0" brightness="4" saturation="1" gamma="4" gamma_threshold="0.01"
       vibrancy="1" contrast="1" white_level="220" temporal_samples="1" cam_zoom="1"
       cam_pitch="0" cam_yaw="0" cam_persp="0" estimator_radius="9" estimator_minimum="0"
       estimator_curve="0.4" mixer_mode="OFF">
  <xform weight="1" color="0" mod_gamma="0" mod_gamma_speed="0" mod_contrast="0"
         mod_saturation="0" mod_hue="0" symmetry="0" material="0" material_speed="0"
         sinusoidal="0.7" swirl="0.3" coefs="0.7 0.2 -0.2 0.7 0 0" chaos="1"/>
  <xform weight="1" color="0.5" symmetry="0" curl="1" curl_c1="0.2" curl_c2="0.1"
         coefs="0.5 0 0 0.5 0.5 0"/>
  <color index="0" rgb="10 20 30"/><color index="255" rgb="250 240 230"/>
</flame>"#;
    let f = parse_flames(jwf, Path::new("jwf.flame")).unwrap().remove(0);
    assert_eq!(f.xforms.len(), 2);
    assert_eq!(f.xforms[1].variations[0].param("curl_c1"), Some(0.2));
    let text = flames_to_string(std::slice::from_ref(&f)).unwrap();
    for kept in [
        r#"mod_gamma="0""#,
        r#"white_level="220""#,
        r#"material="0""#,
    ] {
        assert!(text.contains(kept), "{kept} lost");
    }
    assert!(render_on(1, &f, 1).stats.hits > 0);
}

#[test]
fn png_files_hold_the_rendered_values_at_8_and_16_bits() {
    let f = small(load("m06.flame"), 24, 20.0);
    let img = render_on(2, &f, 3);
    let dir = tempfile::tempdir().unwrap();
    let (p8, p16) = (dir.path().join("a8.png"), dir.path().join("a16.png"));
    img.save_png(&p8, ifslab::render::flame::Depth::Eight, false)
        .unwrap();
    img.save_png(&p16, ifslab::render::flame::Depth::Sixteen, true)
        .unwrap();
    let e8 = image::open(&p8).unwrap().to_rgb8();
    let e16 = image::open(&p16).unwrap();
    assert!(matches!(e16, image::DynamicImage::ImageRgba16(_)));
    let e16 = e16.to_rgba16();
    let mut lit = 0;
    for (k, px) in img.pixels.iter().enumerate() {
        let (x, y) = ((k % 24) as u32, (k / 24) as u32);
        for (c, &v) in px[..3].iter().enumerate() {
            // flam3-render's scales: truncated 8-bit values, 16-bit values up to 255 · 256.
            assert_eq!(e8.get_pixel(x, y)[c], v as u8);
            assert_eq!(e16.get_pixel(x, y)[c], (v as f64 * 256.0) as u16);
        }
        assert_eq!(e16.get_pixel(x, y)[3], (px[3] as f64 * 65535.0) as u16);
        lit += (px[0] > 0.0) as usize;
    }
    assert!(lit > 24, "the test image should not be black");
}

/// `palette="N"` takes flam3's palette N from its library file (Debian flam3-palette,
/// installed by scripts/test.sh); without the file the test says so and checks the error.
#[test]
fn a_palette_number_comes_from_flam3s_library() {
    use ifslab::model::flame::palette::{PaletteLibrary, palette_library_path};
    let text = flame_with(LINEAR, r#"palette="12""#)
        .replace(r#"<color index="0" rgb="255 255 255"/>"#, "");
    let parsed = parse_flames(&text, Path::new("p.flame"));
    let Ok(path) = palette_library_path() else {
        let e = parsed.unwrap_err().to_string();
        assert!(e.contains("flam3-palette"), "{e}");
        eprintln!("note: flam3's palette library is not installed; checked the error only");
        return;
    };
    let lib = PaletteLibrary::load(&path).unwrap();
    let want = lib.get(12, 0.0).unwrap();
    assert_eq!(parsed.unwrap()[0].palette, want);
    let bad = flame_with(LINEAR, r#"palette="123456""#)
        .replace(r#"<color index="0" rgb="255 255 255"/>"#, "");
    let e = parse_flames(&bad, Path::new("p.flame"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("123456") && e.contains("palette"), "{e}");
}
