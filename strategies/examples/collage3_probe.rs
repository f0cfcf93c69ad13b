//! Probe of the collage start in space on one views folder with a truth: every cover's
//! silhouette score, singular values and voxel IoU against the truth, beside the hull's EM
//! code and the truth itself.
//!
//! cargo run --release -p ifslab-strategies --example collage3_probe -- VIEWS K [SEED]
//!
//! VIEWS holds the views and the `truth.json` they were drawn from
//! (`scripts/render3d_views.py`). The environment overrides the search: `CANDIDATES`,
//! `STEPS`, `BATCH`, `AREA` (λ), `SIZEW` (the greedy gain's size weight), `COVERS`,
//! `CONTAIN`, `SMAX` (the largest singular value); `WRITE=DIR` writes each cover as
//! `DIR/cover<i>.json` (for `ifslab invert3d --start-code`). The candidates nearest each
//! truth map are printed last.

use ifslab::metrics3d::voxel_iou;
use ifslab::model::IfsCode;
use ifslab::model::map3::Affine3;
use ifslab_strategies::problems::image3d::{
    CollageSearch3, HullConfig, MapChoice, attractor, collage_candidates3, collage_covers3,
    hull_start, load_views, silhouette_score, visual_hull,
};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = std::path::PathBuf::from(&args[1]);
    let k: usize = args[2].parse().unwrap();
    let seed: u64 = args.get(3).map_or(0, |s| s.parse().unwrap());
    let mut search = CollageSearch3::default();
    if let Ok(v) = std::env::var("AREA") {
        search.area_weight = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("SIZEW") {
        search.size_weight = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("COVERS") {
        search.covers = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("CONTAIN") {
        search.containment = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("SMAX") {
        search.scales.1 = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("STEPS") {
        search.steps = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("BATCH") {
        search.batch = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("CANDIDATES") {
        search.candidates = v.parse().unwrap();
    }
    let views = load_views(&dir).unwrap();
    let cfg = HullConfig::default();
    let hull = visual_hull(&views, &cfg).unwrap();
    let truth = Affine3::from_code(&IfsCode::load(dir.join("truth.json")).unwrap()).unwrap();
    let tp = MapChoice::Determinant.for_affine(&truth);
    let t = attractor(&truth, tp.as_deref(), 1).unwrap();
    let report = |name: &str, maps: &[Affine3]| {
        let p = MapChoice::Determinant.for_affine(maps);
        let pts = attractor(maps, p.as_deref(), 0).unwrap();
        let sil = silhouette_score(&views, maps, 40_000, 0.3, 7).unwrap();
        let iou = voxel_iou(&t, &pts, 64, 1).unwrap();
        let sv: Vec<String> = maps
            .iter()
            .map(|m| {
                let s = m.singular_values();
                format!("{:.2}/{:.2}/{:.2}", s[0], s[1], s[2])
            })
            .collect();
        println!(
            "{name:>10}: silhouettes {sil:.3}  voxel IoU {iou:.3}  [{}]",
            sv.join(" ")
        );
    };
    println!("hull voxels {}", hull.kept.len());
    report("truth", &truth);
    let em = hull_start(&hull, k, &cfg, seed).unwrap();
    let em: Vec<Affine3> = em.iter().map(|m| m.to_affine()).collect();
    report("hull EM", &em);
    let clock = std::time::Instant::now();
    let covers = collage_covers3(&hull, &views, k, seed, &search).unwrap();
    println!("search {:.1} s", clock.elapsed().as_secs_f64());
    for (i, c) in covers.iter().enumerate() {
        report(&format!("cover {i}"), &c.maps);
        if let Ok(out) = std::env::var("WRITE") {
            Affine3::to_code(Some("cover"), &c.maps)
                .unwrap()
                .save(format!("{out}/cover{i}.json"))
                .unwrap();
        }
    }
    let cands = collage_candidates3(&hull, seed, &search).unwrap();
    let held = cands.iter().filter(|c| c.1 >= search.containment).count();
    println!("candidates {} held {held}", cands.len());
    for (j, t) in truth.iter().enumerate() {
        let (mut best, mut at) = (f64::INFINITY, 0);
        for (i, (c, _)) in cands.iter().enumerate() {
            let d = (c.m - t.m).amax().max((c.b - t.b).amax());
            if d < best {
                best = d;
                at = i;
            }
        }
        let c = &cands[at];
        let s = c.0.singular_values();
        println!(
            "truth map {j}: nearest candidate {at} (contained {:.2}) off by {best:.3}, sv {:.2}/{:.2}/{:.2}",
            c.1, s[0], s[1], s[2]
        );
    }
}
