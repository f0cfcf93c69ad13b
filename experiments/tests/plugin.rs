//! A strategy and a map family defined outside ifslab's crates (`examples/plugin.rs`) run
//! through the library's run call: registered, named in a config, checkpointed, logged,
//! summarised — and the run improves on its start.

#[path = "../examples/plugin.rs"]
mod plugin;

#[test]
fn a_strategy_and_a_map_family_from_outside_run_through_the_run_api() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("run");
    let report = plugin::run(&dir).unwrap();
    let s = &report.summary;
    assert_eq!(s["strategy"], "random_search", "{s}");
    assert_eq!(s["iterations"], 60, "{s}");
    // The search kept steps that lowered the cost: the run ends below its start.
    let sel = &s["selection"];
    let start = sel["start"].as_f64().expect("the start was scored");
    let ended = sel[sel["returned"].as_str().unwrap()]
        .as_f64()
        .unwrap_or_else(|| sel["last"].as_f64().unwrap());
    assert!(ended < start, "{sel}");
    // The strategy's statistic is a column of the log, and the code is diagonal.
    let log = std::fs::read_to_string(dir.join("log.csv")).unwrap();
    assert!(log.lines().next().unwrap().contains("accepted"), "{log}");
    let code = ifslab::model::IfsCode::load(dir.join("code.json")).unwrap();
    for m in code.affine2().unwrap() {
        assert!(m.m[(0, 1)] == 0.0 && m.m[(1, 0)] == 0.0, "{m:?}");
    }
    // Registered once: a second registration is refused by name.
    let e = plugin::register().unwrap_err().to_string();
    assert!(e.contains("random_search") && e.contains("already"), "{e}");
    // Unknown names still list what is known, the plugins included.
    let e = ifslab_strategies::problems::image::find_model("nope")
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("diagonal") && e.contains("affine"), "{e}");
}
