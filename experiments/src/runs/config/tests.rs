//! Configs of every problem read, resolved, written back and run by kind; old run folders' configs still load.

use super::*;

const SIERPINSKI: &str = include_str!("../../../configs/sierpinski.toml");

#[test]
fn a_config_without_problem_is_an_image_inversion() {
    let c = RunConfig::from_toml(SIERPINSKI, Path::new("x.toml")).unwrap();
    assert_eq!(c.problem(), "image");
    let t = c.to_table().unwrap();
    assert_eq!(t[PROBLEM_KEY].as_str(), Some("image"));
    // The resolved table reads back as the same config.
    let back = RunConfig::from_table(t, Path::new("x.toml")).unwrap();
    assert_eq!(back, c);
}

#[test]
fn points_texture_and_sdf_configs_resolve_to_tables_that_read_back_the_same() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs");
    for (name, problem) in [
        ("points_triangle.toml", "points"),
        ("points_kitten.toml", "points"),
        ("texture_brick.toml", "texture"),
        ("sdf_koch.toml", "sdf"),
        ("flame_circles3.toml", "flame"),
        ("image3d_tetrahedron.toml", "image3d"),
    ] {
        let c = RunConfig::load(&dir.join(name)).unwrap();
        assert_eq!(c.problem(), problem);
        let t = c.to_table().unwrap();
        assert_eq!(t[PROBLEM_KEY].as_str(), Some(problem));
        let back = RunConfig::from_table(t.clone(), &dir.join("elsewhere/x.toml")).unwrap();
        assert_eq!(back.to_table().unwrap(), t, "{name}");
    }
    // Every choice is written out: the paper's algorithm resolves to its own choices.
    let c = RunConfig::from_toml(
        "problem = \"points\"\ndata = \"ifs:koch\"\npaper = true\n",
        Path::new("x.toml"),
    )
    .unwrap();
    let t = c.to_table().unwrap();
    assert_eq!(t["update"].as_str(), Some("outermost"));
    assert_eq!(t["reorient"].as_integer(), Some(0));
    assert_eq!(t["recentre"].as_bool(), Some(false));
}

#[test]
fn overrides_are_typed_applied_and_validated_like_the_files_own_keys() {
    for (arg, want) in [
        ("iterations=100", toml::Value::Integer(100)),
        ("renderer.sigma = 0.5", toml::Value::Float(0.5)),
        ("model.fixed_probabilities=true", toml::Value::Boolean(true)),
        ("renderer.device=cuda", toml::Value::String("cuda".into())),
        (
            "target.image=\"a b.png\"",
            toml::Value::String("a b.png".into()),
        ),
        (
            "target.image=dir/a=b.png",
            toml::Value::String("dir/a=b.png".into()),
        ),
    ] {
        let (_, v) = parse_override(arg).unwrap();
        assert_eq!(v, want, "{arg}");
    }
    for bad in ["iterations", "=3", "renderer..sigma=1", ".x=1"] {
        assert!(parse_override(bad).is_err(), "{bad}");
    }

    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("s.toml");
    std::fs::write(&path, SIERPINSKI).unwrap();
    let sets = |s: &[&str]| s.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let RunConfig::Image(c) = RunConfig::load_with(
        &path,
        &sets(&["iterations=7", "strategy.adam.lr=0.02", "target.size=64"]),
    )
    .unwrap() else {
        panic!("an image config")
    };
    assert_eq!((c.iterations, c.target.size), (7, 64));
    assert_eq!(c.strategy.name(), "cold_hybrid", "siblings are left alone");
    let base = RunConfig::load(&path).unwrap();
    let RunConfig::Image(b) = &base else { panic!() };
    assert_eq!(b.iterations, 800);
    // A misspelt or ill-typed override is refused by the same checks as the file.
    for (o, want) in [
        ("renderr.sigma=1", "renderr"),
        ("renderer.sigma=-1", "renderer.sigma"),
        ("iterations=lots", "iterations"),
        ("seed.x=1", "`seed` is"),
    ] {
        let e = RunConfig::load_with(&path, &sets(&[o])).unwrap_err();
        assert!(format!("{e:#}").contains(want), "{o}: {e:#}");
    }
    // The device is a key like any other: a build without the GPU backend says how to
    // get one.
    #[cfg(not(feature = "cuda"))]
    {
        let e = RunConfig::load_with(&path, &sets(&["renderer.device=cuda"])).unwrap_err();
        assert!(format!("{e:#}").contains("--features cuda"), "{e:#}");
    }
}

#[test]
fn unknown_problems_and_fields_are_named() {
    let e = RunConfig::from_toml("problem = \"nope\"\n", Path::new("x.toml")).unwrap_err();
    assert!(format!("{e:#}").contains("unknown problem `nope`"), "{e:#}");
    let e = RunConfig::from_toml("problem = 3\n", Path::new("x.toml")).unwrap_err();
    assert!(format!("{e:#}").contains("must be a string"), "{e:#}");
    let text = format!("problem = \"image\"\nbogus = 1\n{SIERPINSKI}");
    let e = RunConfig::from_toml(&text, Path::new("x.toml")).unwrap_err();
    assert!(format!("{e:#}").contains("bogus"), "{e:#}");
}
