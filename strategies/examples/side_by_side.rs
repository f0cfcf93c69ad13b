//! Grey PNGs of one height placed side by side, left to right, into one PNG
//! (`paper_repro/differentiable_ifs/`: target | fit).
//!
//! ```text
//! cargo run --profile ci -p ifslab-strategies --example side_by_side -- OUT.png A.png B.png …
//! ```

use image::{GrayImage, imageops};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 {
        eprintln!("usage: side_by_side OUT.png IN.png [IN.png …]");
        std::process::exit(2);
    }
    let ins: Vec<GrayImage> = args[1..]
        .iter()
        .map(|p| {
            image::open(p)
                .unwrap_or_else(|e| panic!("cannot read {p}: {e}"))
                .to_luma8()
        })
        .collect();
    let h = ins[0].height();
    if let Some((p, i)) = args[1..].iter().zip(&ins).find(|(_, i)| i.height() != h) {
        panic!("{p} is {} pixels high, the first input {h}", i.height());
    }
    let w = ins.iter().map(|i| i.width()).sum();
    let mut out = GrayImage::new(w, h);
    let mut x = 0;
    for i in &ins {
        imageops::replace(&mut out, i, x as i64, 0);
        x += i.width();
    }
    out.save(&args[0])
        .unwrap_or_else(|e| panic!("cannot write {}: {e}", args[0]));
}
