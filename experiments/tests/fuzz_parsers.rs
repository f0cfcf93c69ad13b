//! Parser fuzzing: every input format ifslab reads — code JSON, `.flame` XML, pattern JSON,
//! run configs and sweep files (TOML), point clouds (CSV and `.npy`), PNG and JPEG targets —
//! is fed mutations of seed files (the repository's own, or made here for the binary
//! formats): bytes flipped, cut, repeated and inserted, numbers swapped for NaN, infinities,
//! huge and negative values. Each parse must return, a value or an error, never panic; an
//! error must say something (a refusal with no text names no field).
//!
//! CI runs a bounded number of cases per format (a few seconds in all); for a longer hunt,
//! `PROPTEST_CASES=20000 cargo test --release -p ifslab-experiments --test fuzz_parsers`.
//! A failing input proptest finds is shrunk and its seed recorded in
//! `tests/fuzz_parsers.proptest-regressions`, which then runs first every time.

use std::path::{Path, PathBuf};

use proptest::prelude::*;

use ifslab::model::IfsCode;
use ifslab::model::flame::format::parse_flames;
use ifslab::model::segment::PatternFile;
use ifslab_experiments::runs::RunConfig;
use ifslab_experiments::sweep::SweepConfig;
use ifslab_strategies::problems::em::PointSet;
use ifslab_strategies::problems::em::data::{parse_npy, parse_text};

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
}

fn read(rel: &str) -> Vec<u8> {
    std::fs::read(repo(rel)).unwrap_or_else(|e| panic!("{rel}: {e}"))
}

/// Tokens a mutation may put where a number was.
const HOSTILE: [&str; 10] = [
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e309",
    "-1e309",
    "1e-320",
    "99999999999999999999",
    "-0",
    "4294967296",
];

/// One edit of a byte string.
#[derive(Clone, Debug)]
enum Edit {
    Flip(usize, u8),
    Cut(usize, usize),
    Repeat(usize, usize),
    Insert(usize, Vec<u8>),
    /// Replaces the `n`-th number with a hostile token.
    Number(usize, usize),
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(i, b)| Edit::Flip(i, b)),
        (any::<usize>(), 1usize..64).prop_map(|(i, n)| Edit::Cut(i, n)),
        (any::<usize>(), 1usize..64).prop_map(|(i, n)| Edit::Repeat(i, n)),
        (
            any::<usize>(),
            proptest::collection::vec(any::<u8>(), 1..16)
        )
            .prop_map(|(i, b)| Edit::Insert(i, b)),
        (any::<usize>(), 0..HOSTILE.len()).prop_map(|(n, t)| Edit::Number(n, t)),
        (any::<usize>(), 0..HOSTILE.len()).prop_map(|(n, t)| Edit::Number(n, t)),
    ]
}

fn apply(seed: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut b = seed.to_vec();
    for e in edits {
        let len = b.len().max(1);
        match e {
            Edit::Flip(i, v) => {
                if !b.is_empty() {
                    let i = i % b.len();
                    b[i] = *v;
                }
            }
            Edit::Cut(i, n) => {
                let i = i % len;
                let end = (i + n).min(b.len());
                if i < end {
                    b.drain(i..end);
                }
            }
            Edit::Repeat(i, n) => {
                let i = i % len;
                let end = (i + n).min(b.len());
                if i < end {
                    let part = b[i..end].to_vec();
                    b.splice(end..end, part);
                }
            }
            Edit::Insert(i, bytes) => {
                let i = i % (b.len() + 1);
                b.splice(i..i, bytes.iter().copied());
            }
            Edit::Number(n, t) => {
                let spans = number_spans(&b);
                if !spans.is_empty() {
                    let (s, e) = spans[n % spans.len()];
                    b.splice(s..e, HOSTILE[*t].bytes());
                }
            }
        }
    }
    b
}

/// Byte ranges of the decimal numbers in `b`.
fn number_spans(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < b.len() {
        let starts =
            b[i].is_ascii_digit() || (b[i] == b'-' && b.get(i + 1).is_some_and(u8::is_ascii_digit));
        if starts && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')) {
            let s = i;
            i += 1;
            while i < b.len()
                && (b[i].is_ascii_digit() || matches!(b[i], b'.' | b'e' | b'E' | b'-' | b'+'))
            {
                i += 1;
            }
            out.push((s, i));
        } else {
            i += 1;
        }
    }
    out
}

/// Every refusal must say what is wrong.
fn says_why<T, E: std::fmt::Display>(r: Result<T, E>) -> Result<(), TestCaseError> {
    if let Err(e) = r {
        prop_assert!(!e.to_string().trim().is_empty(), "an error without text");
    }
    Ok(())
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

fn cases() -> ProptestConfig {
    // PROPTEST_CASES moves it for longer runs.
    ProptestConfig {
        cases: std::env::var("PROPTEST_CASES")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(500),
        failure_persistence: Some(Box::new(
            proptest::test_runner::FileFailurePersistence::WithSource("proptest-regressions"),
        )),
        ..ProptestConfig::default()
    }
}

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    proptest::collection::vec(edit(), 1..6)
}

fn small_cloud() -> PointSet {
    let pts: Vec<f64> = (0..40)
        .flat_map(|i| [i as f64 * 0.1, (i * i) as f64 * 0.01])
        .collect();
    PointSet::new(2, pts).unwrap()
}

fn encoded(format: image::ImageFormat) -> Vec<u8> {
    let img = image::RgbImage::from_fn(24, 16, |x, y| {
        image::Rgb([(x * 10) as u8, (y * 15) as u8, 128])
    });
    let mut out = std::io::Cursor::new(Vec::new());
    image::DynamicImage::ImageRgb8(img)
        .write_to(&mut out, format)
        .unwrap();
    out.into_inner()
}

proptest! {
    #![proptest_config(cases())]

    #[test]
    fn code_json_never_panics(e in edits()) {
        let seed = read("tests/fixtures/code/em-adam-fern.json");
        says_why(IfsCode::from_json(&text(&apply(&seed, &e)), Path::new("fuzz.json")))?;
    }

    #[test]
    fn flame_xml_never_panics(e in edits()) {
        let seed = read("paper_repro/fractal_flames/results/fig4_disc/learned.flame");
        says_why(parse_flames(&text(&apply(&seed, &e)), Path::new("fuzz.flame")))?;
    }

    #[test]
    fn pattern_json_never_panics(e in edits()) {
        let seed = read("paper_repro/differentiable_ifs/results/fig2/carpet.pattern.json");
        let origin = Path::new("fuzz.pattern.json");
        match PatternFile::from_json(&text(&apply(&seed, &e)), origin) {
            Ok(file) => says_why(file.pattern(origin))?,
            Err(err) => says_why::<(), _>(Err(err))?,
        }
    }

    #[test]
    fn run_configs_never_panic(e in edits(), which in 0usize..4) {
        let seed = read(["experiments/configs/fern.toml", "experiments/configs/sdf_koch.toml",
            "experiments/configs/points_triangle.toml", "experiments/configs/flame_circles3.toml"][which]);
        let origin = repo("experiments/configs/fuzz.toml");
        says_why(RunConfig::from_toml(&text(&apply(&seed, &e)), &origin))?;
    }

    #[test]
    fn sweep_files_never_panic(e in edits()) {
        let seed = read("paper_repro/ifs_em/sweeps/fig5a.toml");
        says_why(SweepConfig::from_toml(&text(&apply(&seed, &e)), &repo("paper_repro/ifs_em/sweeps/fuzz.toml")))?;
    }

    #[test]
    fn point_csv_never_panics(e in edits()) {
        let seed: Vec<u8> = read("strategies/tests/data/triangle_2k.csv").into_iter().take(4000).collect();
        says_why(parse_text(&text(&apply(&seed, &e)), Path::new("fuzz.csv")))?;
    }

    #[test]
    fn point_npy_never_panics(e in edits()) {
        let seed = small_cloud().to_npy();
        says_why(parse_npy(&apply(&seed, &e), Path::new("fuzz.npy")))?;
    }

    #[test]
    fn png_and_jpeg_targets_never_panic(e in edits(), jpeg in any::<bool>()) {
        let (format, ext) = if jpeg { (image::ImageFormat::Jpeg, "jpg") } else { (image::ImageFormat::Png, "png") };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(format!("fuzz.{ext}"));
        std::fs::write(&path, apply(&encoded(format), &e)).unwrap();
        says_why(ifslab::image::Image::load(&path, false))?;
        says_why(ifslab::image::Image::load_rgba(&path))?;
    }
}

#[test]
fn the_seeds_themselves_parse() {
    // The mutations start from valid files: a fuzz run on broken seeds would test little.
    let code = read("tests/fixtures/code/em-adam-fern.json");
    IfsCode::from_json(&text(&code), Path::new("code.json")).unwrap();
    let flame = read("paper_repro/fractal_flames/results/fig4_disc/learned.flame");
    assert!(
        !parse_flames(&text(&flame), Path::new("f.flame"))
            .unwrap()
            .is_empty()
    );
    let pat = read("paper_repro/differentiable_ifs/results/fig2/carpet.pattern.json");
    PatternFile::from_json(&text(&pat), Path::new("p.json"))
        .unwrap()
        .pattern(Path::new("p.json"))
        .unwrap();
    for c in ["fern", "sdf_koch", "points_triangle", "flame_circles3"] {
        let p = repo(&format!("experiments/configs/{c}.toml"));
        RunConfig::from_toml(&std::fs::read_to_string(&p).unwrap(), &p).unwrap();
    }
    let sweep = repo("paper_repro/ifs_em/sweeps/fig5a.toml");
    SweepConfig::from_toml(&std::fs::read_to_string(&sweep).unwrap(), &sweep).unwrap();
    let csv: Vec<u8> = read("strategies/tests/data/triangle_2k.csv")
        .into_iter()
        .take(4000)
        .collect();
    // Cut mid-line: all but the last line parse; the seed is the whole lines.
    let whole = &csv[..=csv.iter().rposition(|&b| b == b'\n').unwrap()];
    parse_text(&text(whole), Path::new("t.csv")).unwrap();
    parse_npy(&small_cloud().to_npy(), Path::new("c.npy")).unwrap();
    assert!(
        number_spans(b"a1 [-2.5e3, 7]").len() == 2,
        "{:?}",
        number_spans(b"a1 [-2.5e3, 7]")
    );
}

/// The regression corpus (`tests/corpus/`): hostile inputs of every format, each refused
/// without a panic and with the words `tests/corpus/expect.toml` pins for it (the field or
/// the reason). Every file is listed there and every listed file exists, so an input added
/// to the corpus (a crash a fuzz run found, say) must say what its refusal names.
#[test]
fn the_regression_corpus_is_refused_by_name() {
    let root = repo("experiments/tests/corpus");
    let expect: toml::Table = std::fs::read_to_string(root.join("expect.toml"))
        .unwrap()
        .parse()
        .unwrap();
    let mut files = Vec::new();
    for dir in std::fs::read_dir(&root).unwrap() {
        let dir = dir.unwrap().path();
        if dir.is_dir() {
            for f in std::fs::read_dir(&dir).unwrap() {
                files.push(f.unwrap().path());
            }
        }
    }
    files.sort();
    let scratch = tempfile::tempdir().unwrap();
    let mut failures = Vec::new();
    for path in &files {
        let rel = path
            .strip_prefix(&root)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        let format = rel.split('/').next().unwrap().to_string();
        let bytes = std::fs::read(path).unwrap();
        // Images are decoded from a file: a copy, so the corpus is never written.
        let at = if format == "image" {
            scratch.path().join(path.file_name().unwrap())
        } else {
            path.clone()
        };
        let outcome = std::panic::catch_unwind(move || {
            ifslab_experiments::inputs::parse(&format, &bytes, &at)
        });
        let wants: Vec<String> = match expect.get(&rel) {
            Some(toml::Value::String(w)) => vec![w.clone()],
            Some(toml::Value::Array(a)) => a
                .iter()
                .filter_map(|v| v.as_str().map(String::from))
                .collect(),
            _ => {
                failures.push(format!("{rel}: not listed in expect.toml"));
                continue;
            }
        };
        match outcome {
            Err(_) => failures.push(format!("{rel}: panicked")),
            Ok(Ok(())) => failures.push(format!("{rel}: accepted")),
            Ok(Err(msg)) => {
                for w in &wants {
                    if !msg.contains(w.as_str()) {
                        failures.push(format!("{rel}: `{w}` not in: {msg}"));
                    }
                }
            }
        }
    }
    for listed in expect.keys() {
        if !root.join(listed).is_file() {
            failures.push(format!("{listed}: listed in expect.toml but missing"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
