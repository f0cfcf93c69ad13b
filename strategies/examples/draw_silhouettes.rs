//! Two silhouettes drawn with tiny-skia as fit targets (`paper_repro/differentiable_ifs/`,
//! in place of the MPEG-7 apple and flower the paper used, which are not here): a filled
//! apple (body of two lobes, stem, leaf) and a five-petal flower, dark on white, anti-aliased.
//!
//! ```text
//! cargo run --profile ci -p ifslab-strategies --example draw_silhouettes -- OUT_DIR [SIZE]
//! ```
//! writes `OUT_DIR/apple.png` and `OUT_DIR/flower.png`, `SIZE`² pixels (default 128).

use std::f32::consts::PI;
use std::path::PathBuf;

use tiny_skia::{Color, FillRule, Paint, PathBuilder, Pixmap, Transform};

/// The apple in a unit box (y down): two lobes joined by cubic curves, a stem and a leaf.
fn apple(pb: &mut PathBuilder) {
    pb.move_to(0.5, 0.3);
    pb.cubic_to(0.62, 0.18, 0.92, 0.2, 0.9, 0.52);
    pb.cubic_to(0.88, 0.78, 0.72, 0.92, 0.6, 0.9);
    pb.cubic_to(0.55, 0.89, 0.45, 0.89, 0.4, 0.9);
    pb.cubic_to(0.28, 0.92, 0.12, 0.78, 0.1, 0.52);
    pb.cubic_to(0.08, 0.2, 0.38, 0.18, 0.5, 0.3);
    pb.close();
    // Stem.
    pb.move_to(0.48, 0.31);
    pb.cubic_to(0.47, 0.2, 0.5, 0.12, 0.55, 0.07);
    pb.line_to(0.58, 0.09);
    pb.cubic_to(0.54, 0.14, 0.52, 0.21, 0.53, 0.31);
    pb.close();
    // Leaf.
    pb.move_to(0.55, 0.16);
    pb.cubic_to(0.62, 0.06, 0.74, 0.05, 0.8, 0.09);
    pb.cubic_to(0.74, 0.17, 0.64, 0.2, 0.55, 0.16);
    pb.close();
}

/// The flower: r(φ) = 0.27 + 0.17·cos(5φ) around the centre, on 400 points.
fn flower(pb: &mut PathBuilder) {
    let n = 400;
    for k in 0..n {
        let phi = 2.0 * PI * k as f32 / n as f32;
        let r = 0.27 + 0.17 * (5.0 * phi).cos();
        let (x, y) = (
            0.5 + r * (phi - PI / 2.0).cos(),
            0.5 + r * (phi - PI / 2.0).sin(),
        );
        if k == 0 {
            pb.move_to(x, y);
        } else {
            pb.line_to(x, y);
        }
    }
    pb.close();
}

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().unwrap_or_else(|| {
        eprintln!("usage: draw_silhouettes OUT_DIR [SIZE]");
        std::process::exit(2)
    }));
    let size: u32 = args
        .next()
        .map(|s| s.parse().unwrap_or_else(|e| panic!("SIZE `{s}`: {e}")))
        .unwrap_or(128);
    assert!(size >= 8, "SIZE must be at least 8 pixels, got {size}");
    std::fs::create_dir_all(&dir)
        .unwrap_or_else(|e| panic!("cannot create {}: {e}", dir.display()));
    for (name, draw) in [("apple", apple as fn(&mut PathBuilder)), ("flower", flower)] {
        let mut pixmap = Pixmap::new(size, size).expect("a non-empty pixmap");
        pixmap.fill(Color::WHITE);
        let mut pb = PathBuilder::new();
        draw(&mut pb);
        let path = pb.finish().expect("a non-empty path");
        let mut paint = Paint::default();
        paint.set_color(Color::BLACK);
        paint.anti_alias = true;
        let s = size as f32;
        pixmap.fill_path(
            &path,
            &paint,
            FillRule::Winding,
            Transform::from_scale(s, s),
            None,
        );
        let out = dir.join(format!("{name}.png"));
        pixmap
            .save_png(&out)
            .unwrap_or_else(|e| panic!("cannot write {}: {e}", out.display()));
        println!("wrote {}", out.display());
    }
}
