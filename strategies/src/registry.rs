//! The open strategy registry: every strategy a run can name, one registration line each.
//!
//! A strategy is two things: its hyper-parameters (a [`Params`] type: serde, defaults,
//! validation, the name configs use and the statistics it logs) and an argmin
//! [`Solver`] built from them. [`strategies`] lists them for a problem type `P`; a run
//! looks its `[strategy] kind = "…"` up there, builds an [`AnySolver`] (the solver behind a
//! box, so the executor, the checkpoint and the log are written once for all of them) and
//! logs the statistics the strategy reports (annealing acceptances, noise levels, …) as
//! columns of `log.csv`.
//!
//! Adding a strategy to this crate: a folder `src/<name>/` with its `Params` type and its
//! `Solver`, and one line in [`builtin_strategies`]. From another crate, without editing
//! this one: implement [`StrategyPlugin`] and call
//! [`register_strategy`](crate::plugins::register_strategy) once before the run (or
//! [`register_for`] for a problem type of your own); `experiments/examples/plugin.rs` does
//! it and runs the result through `ifslab run`'s library call. Gradient strategies need
//! [`Differentiable`]; value-only ones (annealing today, evolutionary ones tomorrow) need
//! only [`Anneal`]'s cost, but every problem in the registry offers both.

use std::any::{Any, TypeId};
use std::collections::HashMap;
use std::sync::{LazyLock, RwLock};

use argmin::core::{Error as ArgminError, KV, Problem, Solver, TerminationStatus};
use serde::de::{DeserializeOwned, Deserializer};
use serde::ser::Serializer;
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, RunSpec};
use crate::error::{Error, Result};
use crate::optim::adam::{Adam, AdamConfig};
use crate::optim::annealing::{Anneal, AnnealingConfig, SimulatedAnnealing};
use crate::optim::cmaes::{Cmaes, CmaesConfig};
use crate::optim::cuckoo::{Cuckoo, CuckooConfig};
use crate::optim::evolutionary::{Evolutionary, EvolutionaryConfig};
use crate::optim::gd::{GdConfig, GradientDescent};
use crate::optim::hybrid::{ColdHybridConfig, Hybrid, HybridConfig};
use crate::optim::learning_fractals::{LearningFractals, LearningFractalsConfig};
use crate::optim::noisy::{NoisyAdam, NoisyConfig};
use crate::optim::swarm::{Swarm, SwarmConfig};

/// A problem every registered strategy can run on: a loss with its gradient, and a cheap
/// cost on a chosen random stream.
pub trait StrategyProblem: Differentiable + Anneal + 'static {}
impl<P: Differentiable + Anneal + 'static> StrategyProblem for P {}

/// A solver behind a box: argmin's `Solver` for one problem type, plus its state as JSON.
pub trait ErasedSolver<P>: Send {
    /// argmin's `init`.
    fn init(
        &mut self,
        problem: &mut Problem<P>,
        state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError>;
    /// argmin's `next_iter`.
    fn next_iter(
        &mut self,
        problem: &mut Problem<P>,
        state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError>;
    /// argmin's `terminate`.
    fn terminate(&mut self, state: &GradState) -> TerminationStatus;
    /// The solver's whole state (for checkpoints).
    fn to_json(&self) -> serde_json::Result<serde_json::Value>;
}

impl<P, S> ErasedSolver<P> for S
where
    S: Solver<P, GradState> + Serialize + Send,
{
    fn init(
        &mut self,
        problem: &mut Problem<P>,
        state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError> {
        Solver::init(self, problem, state)
    }
    fn next_iter(
        &mut self,
        problem: &mut Problem<P>,
        state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError> {
        Solver::next_iter(self, problem, state)
    }
    fn terminate(&mut self, state: &GradState) -> TerminationStatus {
        Solver::terminate(self, state)
    }
    fn to_json(&self) -> serde_json::Result<serde_json::Value> {
        serde_json::to_value(self)
    }
}

/// Any registered strategy's solver for problem `P`; it checkpoints as `{kind, solver}` and
/// is restored through the registry.
pub struct AnySolver<P> {
    kind: &'static str,
    inner: Box<dyn ErasedSolver<P>>,
}

impl<P> AnySolver<P> {
    /// The strategy's name.
    pub fn kind(&self) -> &'static str {
        self.kind
    }
}

impl<P> Solver<P, GradState> for AnySolver<P> {
    fn name(&self) -> &str {
        self.kind
    }
    fn init(
        &mut self,
        problem: &mut Problem<P>,
        state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError> {
        self.inner.init(problem, state)
    }
    fn next_iter(
        &mut self,
        problem: &mut Problem<P>,
        state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError> {
        self.inner.next_iter(problem, state)
    }
    fn terminate(&mut self, state: &GradState) -> TerminationStatus {
        self.inner.terminate(state)
    }
}

#[derive(Serialize, Deserialize)]
struct SolverRecord {
    kind: String,
    solver: serde_json::Value,
}

impl<P> Serialize for AnySolver<P> {
    fn serialize<Ser: Serializer>(&self, s: Ser) -> std::result::Result<Ser::Ok, Ser::Error> {
        let solver = self.inner.to_json().map_err(serde::ser::Error::custom)?;
        SolverRecord {
            kind: self.kind.to_owned(),
            solver,
        }
        .serialize(s)
    }
}

impl<'de, P: StrategyProblem> Deserialize<'de> for AnySolver<P> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let rec = SolverRecord::deserialize(d)?;
        let entry = find::<P>(&rec.kind).map_err(serde::de::Error::custom)?;
        (entry.restore)(rec.solver).map_err(serde::de::Error::custom)
    }
}

type BuildFn<P> = Box<dyn Fn(&toml::Table, &RunSpec) -> Result<AnySolver<P>> + Send + Sync>;
type RestoreFn<P> = fn(serde_json::Value) -> Result<AnySolver<P>>;

/// One registered strategy for problem type `P`.
pub struct StrategyEntry<P> {
    /// Its name in configs.
    pub kind: &'static str,
    /// The statistics it logs.
    pub stats: &'static [&'static str],
    /// Its default hyper-parameters as a TOML table.
    pub defaults: fn() -> toml::Table,
    /// Reads, completes (defaults filled in) and validates hyper-parameters.
    pub resolve: fn(&toml::Table) -> Result<toml::Table>,
    build: BuildFn<P>,
    restore: RestoreFn<P>,
}

impl<P: StrategyProblem> StrategyEntry<P> {
    /// Registers the strategy whose hyper-parameters are `C` and whose solver `make` builds.
    pub fn new<C, S>(make: fn(C, &RunSpec) -> Result<S>) -> Self
    where
        C: Params,
        S: Solver<P, GradState> + Serialize + DeserializeOwned + Send + 'static,
    {
        StrategyEntry {
            kind: C::KIND,
            stats: C::STATS,
            defaults: || to_table(&C::default()).expect("defaults serialise"),
            resolve: |t| to_table(&parse::<C>(t)?),
            build: Box::new(move |t, run| {
                Ok(AnySolver {
                    kind: C::KIND,
                    inner: Box::new(make(parse::<C>(t)?, run)?),
                })
            }),
            restore: |v| {
                let solver: S = serde_json::from_value(v).map_err(|e| {
                    Error::InvalidInput(format!("checkpoint's {} solver: {e}", C::KIND))
                })?;
                Ok(AnySolver {
                    kind: C::KIND,
                    inner: Box::new(solver),
                })
            },
        }
    }

    /// Builds the solver from (unresolved or resolved) hyper-parameters.
    pub fn build(&self, params: &toml::Table, run: &RunSpec) -> Result<AnySolver<P>> {
        (self.build)(params, run)
    }
}

/// Every strategy a run can name, for problem type `P`: this crate's
/// ([`builtin_strategies`]) and then those registered for `P` from outside ([`register_for`]).
pub fn strategies<P: StrategyProblem>() -> Vec<StrategyEntry<P>> {
    let mut all = builtin_strategies::<P>();
    let registered = REGISTERED.read().unwrap_or_else(|e| e.into_inner());
    if let Some(list) = registered.get(&TypeId::of::<P>()) {
        all.extend(
            list.iter()
                .filter_map(|f| f.downcast_ref::<fn() -> StrategyEntry<P>>())
                .map(|f| f()),
        );
    }
    all
}

/// A strategy defined outside this crate: its entry for any problem type (usually one line,
/// `StrategyEntry::new(|c: MyConfig, run| MySolver::new(c, run.iterations, run.seed))`).
pub trait StrategyPlugin: 'static {
    /// The strategy's entry for problem type `P`.
    fn entry<P: StrategyProblem>() -> StrategyEntry<P>;
}

/// Strategies registered from outside, per problem type: `fn() -> StrategyEntry<P>` behind
/// `Any`, keyed by `P`'s type.
type Registered = HashMap<TypeId, Vec<Box<dyn Any + Send + Sync>>>;
static REGISTERED: LazyLock<RwLock<Registered>> = LazyLock::new(Default::default);

/// Makes the strategy whose entry `entry` builds available to runs of problem type `P` (and
/// to config checks when `P` is [`ParamsOnly`]), for the rest of the process. A name that is
/// taken for `P` is refused.
pub fn register_for<P: StrategyProblem>(entry: fn() -> StrategyEntry<P>) -> Result<()> {
    let kind = entry().kind;
    // Checked and added under one lock: two threads registering one name cannot both win.
    let mut registered = REGISTERED.write().unwrap_or_else(|e| e.into_inner());
    let list = registered.entry(TypeId::of::<P>()).or_default();
    let taken = builtin_strategies::<P>().iter().any(|e| e.kind == kind)
        || list
            .iter()
            .filter_map(|f| f.downcast_ref::<fn() -> StrategyEntry<P>>())
            .any(|f| f().kind == kind);
    if taken {
        return Err(Error::param(
            "strategy",
            format!("a strategy called `{kind}` is already registered"),
        ));
    }
    list.push(Box::new(entry));
    Ok(())
}

/// The strategies of this crate, for problem type `P`: **one line per strategy**.
pub fn builtin_strategies<P: StrategyProblem>() -> Vec<StrategyEntry<P>> {
    vec![
        StrategyEntry::new(|c: HybridConfig, r| Hybrid::new(c, r.iterations, r.seed)),
        StrategyEntry::new(|c: ColdHybridConfig, r| Hybrid::new(c.0, r.iterations, r.seed)),
        StrategyEntry::new(|c: AdamConfig, _| Adam::new(c)),
        StrategyEntry::new(|c: AnnealingConfig, r| {
            SimulatedAnnealing::new(c, r.iterations, r.seed)
        }),
        StrategyEntry::new(|c: NoisyConfig, r| NoisyAdam::new(c, r.seed)),
        StrategyEntry::new(|c: GdConfig, _| GradientDescent::new(c)),
        StrategyEntry::new(|c: EvolutionaryConfig, r| Evolutionary::new(c, r.iterations, r.seed)),
        StrategyEntry::new(|c: CmaesConfig, r| Cmaes::new(c, r.iterations, r.seed)),
        StrategyEntry::new(|c: CuckooConfig, r| Cuckoo::new(c, r.iterations, r.seed)),
        StrategyEntry::new(|c: SwarmConfig, r| Swarm::new(c, r.iterations, r.seed)),
        StrategyEntry::new(|c: LearningFractalsConfig, r| {
            LearningFractals::new(c, r.iterations, r.seed)
        }),
    ]
}

/// The names of the registered strategies, in registry order.
pub fn kinds() -> Vec<&'static str> {
    strategies::<ParamsOnly>().iter().map(|e| e.kind).collect()
}

/// The entry called `kind`.
pub fn find<P: StrategyProblem>(kind: &str) -> Result<StrategyEntry<P>> {
    strategies::<P>()
        .into_iter()
        .find(|e| e.kind == kind)
        .ok_or_else(|| {
            Error::param(
                "strategy",
                format!(
                    "unknown strategy `{kind}`; choose one of {}",
                    kinds().join(", ")
                ),
            )
        })
}

/// Resolves `params` for the strategy `kind` (defaults filled in, values validated) without
/// a problem type (configs are read before the problem exists).
pub fn resolve(kind: &str, params: &toml::Table) -> Result<toml::Table> {
    (find::<ParamsOnly>(kind)?.resolve)(params)
}

/// The default hyper-parameters of the strategy `kind`.
pub fn defaults(kind: &str) -> Result<toml::Table> {
    Ok((find::<ParamsOnly>(kind)?.defaults)())
}

/// The statistics the strategy `kind` logs.
pub fn stats(kind: &str) -> Result<&'static [&'static str]> {
    Ok(find::<ParamsOnly>(kind)?.stats)
}

/// `C` from a table laid over `C::default()` (nested tables merged key by key), so a
/// strategy's own defaults fill what a config leaves out even when they differ from its
/// fields' types' defaults (`cold_hybrid`).
fn parse<C: Params>(t: &toml::Table) -> Result<C> {
    let mut full = to_table(&C::default())?;
    overlay(&mut full, t);
    let c: C = crate::recipe::from_table(full).map_err(|e| {
        Error::InvalidInput(format!("config section `strategy` ({}): {e}", C::KIND))
    })?;
    c.validate()?;
    Ok(c)
}

fn overlay(base: &mut toml::Table, top: &toml::Table) {
    for (k, v) in top {
        match (base.get_mut(k), v) {
            (Some(toml::Value::Table(b)), toml::Value::Table(t)) => overlay(b, t),
            _ => {
                base.insert(k.clone(), v.clone());
            }
        }
    }
}

fn to_table<C: Serialize>(c: &C) -> Result<toml::Table> {
    match toml::Value::try_from(c) {
        Ok(toml::Value::Table(t)) => Ok(t),
        Ok(_) => Err(Error::InvalidInput(
            "strategy parameters must be a table".into(),
        )),
        Err(e) => Err(Error::InvalidInput(format!(
            "strategy parameters do not serialise: {e}"
        ))),
    }
}

/// A problem type for the registry's problem-independent parts (names, defaults,
/// resolution); it is never evaluated.
pub struct ParamsOnly;

impl Differentiable for ParamsOnly {
    fn evaluate(&self, _theta: &[f64], _iter: u64) -> Result<crate::driver::Evaluation> {
        Err(Error::InvalidInput(
            "ParamsOnly is not a problem to evaluate".into(),
        ))
    }
}

impl Anneal for ParamsOnly {
    fn anneal_cost(&self, _theta: &[f64], _stream: u64, _frac: f64) -> Result<f64> {
        Err(Error::InvalidInput(
            "ParamsOnly is not a problem to evaluate".into(),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_strategy_resolves_its_defaults_and_names_are_unique() {
        let ks = kinds();
        let mut sorted = ks.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), ks.len(), "{ks:?}");
        for k in ks {
            let d = defaults(k).unwrap();
            assert_eq!(resolve(k, &d).unwrap(), d, "{k}");
            assert_eq!(resolve(k, &toml::Table::new()).unwrap(), d, "{k}");
        }
    }

    #[test]
    fn a_strategy_s_own_defaults_fill_what_a_config_leaves_out() {
        let mut t = toml::Table::new();
        t.insert("anneal_every".into(), toml::Value::Integer(100));
        let r = resolve("cold_hybrid", &t).unwrap();
        assert_eq!(r["anneal_every"].as_integer(), Some(100));
        assert_eq!(r["annealing"]["temperature"].as_float(), Some(0.02));
        assert_eq!(r["adam"]["final_lr_factor"].as_float(), Some(0.1));
        let paper = resolve("hybrid", &t).unwrap();
        assert_eq!(paper["annealing"]["temperature"].as_float(), Some(1.0));
    }

    #[test]
    fn unknown_kinds_and_fields_are_named() {
        let e = resolve("no_such_strategy", &toml::Table::new())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("no_such_strategy") && e.contains("hybrid"),
            "{e}"
        );
        let mut t = toml::Table::new();
        t.insert("lr_typo".into(), toml::Value::Float(0.1));
        let e = resolve("adam", &t).unwrap_err().to_string();
        assert!(e.contains("lr_typo"), "{e}");
    }
}
