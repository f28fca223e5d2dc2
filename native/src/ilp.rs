//! The one place that builds good_lp models, runs HiGHS and maps its statuses: 0/1 programs
//! for expression packing (maximum-weight independent sets, colourings) and landmark layouts
//! (weighted set cover).

use good_lp::solvers::highs::highs;
use good_lp::{variable, Expression, ProblemVariables, SolverModel, Variable};
use highs::{HighsModelStatus, HighsSolutionStatus};
use serde::Serialize;
use std::sync::{mpsc, Mutex};

use crate::error::{ShapesmithError, ShapesmithResult};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sense {
    Maximise,
    Minimise,
}

/// `lower <= sum(coefficient * x_variable) <= upper`.
#[derive(Clone, Debug)]
pub struct Row {
    pub terms: Vec<(usize, f64)>,
    pub lower: f64,
    pub upper: f64,
}

/// Optimise `objective . x` over x in {0, 1}^n subject to the rows.
#[derive(Clone, Debug)]
pub struct BinaryProgram {
    pub sense: Sense,
    pub objective: Vec<f64>,
    pub rows: Vec<Row>,
}

impl BinaryProgram {
    pub fn new(sense: Sense, objective: Vec<f64>) -> Self {
        Self { sense, objective, rows: Vec::new() }
    }

    pub fn n_variables(&self) -> usize {
        self.objective.len()
    }

    pub fn at_most(&mut self, terms: Vec<(usize, f64)>, upper: f64) {
        self.rows.push(Row { terms, lower: f64::NEG_INFINITY, upper });
    }

    pub fn at_least(&mut self, terms: Vec<(usize, f64)>, lower: f64) {
        self.rows.push(Row { terms, lower, upper: f64::INFINITY });
    }

    pub fn equal(&mut self, terms: Vec<(usize, f64)>, value: f64) {
        self.rows.push(Row { terms, lower: value, upper: value });
    }

    /// The objective of a 0/1 assignment, and whether it satisfies every row (to 1e-9).
    pub fn evaluate(&self, x: &[bool]) -> (f64, bool) {
        let objective = self.objective.iter().zip(x).filter(|p| *p.1).map(|p| p.0).sum();
        let feasible = self.rows.iter().all(|row| {
            let s: f64 = row.terms.iter().filter(|t| x[t.0]).map(|t| t.1).sum();
            s >= row.lower - 1e-9 && s <= row.upper + 1e-9
        });
        (objective, feasible)
    }
}

#[derive(Clone, Debug, Default)]
pub struct IlpOptions {
    /// Seconds; `None` solves to proven optimality however long it takes.
    pub time_limit: Option<f64>,
    /// Skip HiGHS's feasibility-jump heuristic, a search for a first feasible point with a
    /// fixed work budget: the packing's programs are small (tens of nodes), the solve proves
    /// their optimum at once without it, and it was two thirds of the solver's instructions
    /// in a packing of the bundled head (callgrind).
    pub skip_feasibility_jump: bool,
}

/// How far the returned solution is known to be from the optimum.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SolveStatus {
    /// Proven optimal (HiGHS closed the gap).
    Optimal,
    /// Stopped inside HiGHS's gap tolerance: feasible, possibly not optimal.
    GapLimit,
    /// Stopped by the time limit: feasible, not proven optimal.
    TimeLimit,
}

impl SolveStatus {
    pub fn is_optimal(self) -> bool {
        self == SolveStatus::Optimal
    }
}

#[derive(Clone, Debug)]
pub struct IlpSolution {
    pub x: Vec<bool>,
    pub objective: f64,
    pub status: SolveStatus,
}

/// A MIP gap at most this (relative) counts as closed: HiGHS reports float noise such as 1e-16
/// on programs it has solved to optimality.
pub const OPTIMALITY_GAP: f64 = 1e-9;

/// Solves the program with HiGHS (gaps set to zero so that "optimal" means proven optimal).
/// Errors: [`ShapesmithError::Infeasible`] when no 0/1 point satisfies the rows,
/// [`ShapesmithError::Solver`] for anything else HiGHS reports.
pub fn solve_binary(program: &BinaryProgram, options: &IlpOptions) -> ShapesmithResult<IlpSolution> {
    let (program, options) = (program.clone(), options.clone());
    on_solver_thread(move || solve_here(&program, &options))
}

type SolverJob = Box<dyn FnOnce() + Send>;

/// The queue of [`SOLVER_THREAD`]'s jobs; `None` until the first solve.
static SOLVER_QUEUE: Mutex<Option<mpsc::Sender<SolverJob>>> = Mutex::new(None);

/// Name of the one thread that runs HiGHS.
const SOLVER_THREAD: &str = "shapesmith-highs";

/// Runs `job` on one thread kept for the life of the process, one job at a time, and waits.
///
/// HiGHS gives each calling thread a task scheduler of its own and shuts it down from a C++
/// thread-local destructor when that thread exits (HiGHS pull request 818). Solving on
/// short-lived threads (a rayon pool dropped after a parallel section, a test harness's thread
/// per test) runs that destructor every time; in the Windows build, with MinGW's runtime linked
/// statically, it hung or crashed at thread exit under wine (`scripts/test-windows`, issue of
/// 2026-11-30). On this thread the scheduler is made once and never torn down, and the solves
/// are serialised, which HiGHS's process-wide state needs anyway.
fn on_solver_thread<R: Send + 'static>(
    job: impl FnOnce() -> ShapesmithResult<R> + Send + 'static,
) -> ShapesmithResult<R> {
    let (reply, answer) = mpsc::sync_channel(1);
    let job: SolverJob = Box::new(move || {
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(job))
            .unwrap_or_else(|_| Err(ShapesmithError::Solver("the 0/1 solve panicked".into())));
        // The caller waits on `answer` until this send; it cannot have gone.
        let _ = reply.send(result);
    });
    {
        let mut queue = SOLVER_QUEUE.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        let unsent = match queue.as_ref() {
            Some(sender) => sender.send(job).err().map(|mpsc::SendError(job)| job),
            None => Some(job),
        };
        if let Some(job) = unsent {
            let (sender, jobs) = mpsc::channel::<SolverJob>();
            std::thread::Builder::new()
                .name(SOLVER_THREAD.into())
                .spawn(move || jobs.into_iter().for_each(|job| job()))
                .map_err(|e| ShapesmithError::Solver(format!("cannot start the solver thread: {e}")))?;
            sender.send(job).map_err(|_| ShapesmithError::Solver("the solver thread stopped".into()))?;
            *queue = Some(sender);
        }
    }
    answer.recv().unwrap_or_else(|_| Err(ShapesmithError::Solver("the solver thread stopped".into())))
}

/// [`solve_binary`] on the calling thread.
fn solve_here(program: &BinaryProgram, options: &IlpOptions) -> ShapesmithResult<IlpSolution> {
    if program.n_variables() == 0 {
        let feasible = program.rows.iter().all(|r| r.lower <= 0.0 && r.upper >= 0.0);
        return if feasible {
            Ok(IlpSolution { x: Vec::new(), objective: 0.0, status: SolveStatus::Optimal })
        } else {
            Err(ShapesmithError::Infeasible("a constraint cannot be met with no variables".into()))
        };
    }
    let mut vars = ProblemVariables::new();
    let x: Vec<Variable> = (0..program.n_variables()).map(|_| vars.add(variable().binary())).collect();
    let linear = |terms: &mut dyn Iterator<Item = (usize, f64)>| -> Expression {
        terms.fold(Expression::from(0.0), |e, (i, c)| e + c * x[i])
    };
    let objective = linear(&mut program.objective.iter().copied().enumerate());
    let unsolved = match program.sense {
        Sense::Maximise => vars.maximise(objective),
        Sense::Minimise => vars.minimise(objective),
    };
    let mut model = highs(unsolved);
    for row in &program.rows {
        let expr = linear(&mut row.terms.iter().copied());
        if row.lower == row.upper {
            model = model.with(expr.eq(row.lower));
            continue;
        }
        if row.lower.is_finite() {
            model = model.with(expr.clone().geq(row.lower));
        }
        if row.upper.is_finite() {
            model = model.with(expr.leq(row.upper));
        }
    }
    let mut highs_model = model
        .try_into_inner()
        .map_err(|e| ShapesmithError::Solver(format!("HiGHS rejected the model: {e}")))?;
    highs_model.set_option("output_flag", false);
    highs_model.set_option("threads", 1);
    highs_model.set_option("mip_rel_gap", 0.0);
    highs_model.set_option("mip_abs_gap", 0.0);
    if options.skip_feasibility_jump {
        highs_model.set_option("mip_heuristic_run_feasibility_jump", false);
    }
    if let Some(limit) = options.time_limit {
        highs_model.set_option("time_limit", limit);
    }
    let solved = highs_model.try_solve().map_err(|e| ShapesmithError::Solver(format!("HiGHS failed: {e:?}")))?;
    let status = match solved.status() {
        HighsModelStatus::Optimal if solved.mip_gap().is_finite() && solved.mip_gap() > OPTIMALITY_GAP => {
            SolveStatus::GapLimit
        }
        HighsModelStatus::Optimal => SolveStatus::Optimal,
        HighsModelStatus::ReachedTimeLimit
        | HighsModelStatus::ReachedIterationLimit
        | HighsModelStatus::ReachedSolutionLimit
        | HighsModelStatus::ReachedInterrupt => SolveStatus::TimeLimit,
        HighsModelStatus::Infeasible | HighsModelStatus::UnboundedOrInfeasible => {
            return Err(ShapesmithError::Infeasible("the 0/1 program has no feasible solution".into()))
        }
        other => return Err(ShapesmithError::Solver(format!("HiGHS stopped with status {other:?}"))),
    };
    if solved.primal_solution_status() != HighsSolutionStatus::Feasible {
        return Err(ShapesmithError::Solver("HiGHS stopped before finding any feasible point".into()));
    }
    let columns = solved.get_solution();
    // good_lp adds one HiGHS column per variable, in creation order.
    let values: Vec<bool> = columns.columns()[..x.len()].iter().map(|&v| v > 0.5).collect();
    let (objective, feasible) = program.evaluate(&values);
    if !feasible {
        return Err(ShapesmithError::Solver("HiGHS returned a point that violates a constraint".into()));
    }
    Ok(IlpSolution { x: values, objective, status })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn brute_force(p: &BinaryProgram) -> Option<f64> {
        let n = p.n_variables();
        let mut best: Option<f64> = None;
        for mask in 0u32..(1 << n) {
            let x: Vec<bool> = (0..n).map(|i| mask >> i & 1 == 1).collect();
            let (obj, ok) = p.evaluate(&x);
            if ok {
                best = Some(match (best, p.sense) {
                    (None, _) => obj,
                    (Some(b), Sense::Maximise) => b.max(obj),
                    (Some(b), Sense::Minimise) => b.min(obj),
                });
            }
        }
        best
    }

    #[test]
    fn random_programs_match_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for trial in 0..40 {
            let n = rng.random_range(1..11);
            let sense = if trial % 2 == 0 { Sense::Maximise } else { Sense::Minimise };
            let mut p = BinaryProgram::new(sense, (0..n).map(|_| rng.random_range(0.1..2.0)).collect());
            for _ in 0..rng.random_range(0..8) {
                let terms: Vec<(usize, f64)> =
                    (0..n).filter(|_| rng.random_bool(0.4)).map(|i| (i, 1.0)).collect();
                match sense {
                    Sense::Maximise => p.at_most(terms, 1.0),
                    Sense::Minimise => p.at_least(terms, 1.0),
                }
            }
            match (solve_binary(&p, &IlpOptions::default()), brute_force(&p)) {
                (Ok(sol), Some(best)) => {
                    assert_eq!(sol.status, SolveStatus::Optimal);
                    assert!((sol.objective - best).abs() < 1e-9, "trial {trial}: {} vs {best}", sol.objective);
                }
                (Err(ShapesmithError::Infeasible(_)), None) => {}
                (got, want) => panic!("trial {trial}: solver {got:?}, brute force {want:?}"),
            }
        }
    }

    #[test]
    fn every_solve_runs_on_the_one_solver_thread() {
        // Callers on threads that come and go (here short-lived rayon pools, dropped after use)
        // all reach the same long-lived thread, never their own.
        let runner = || on_solver_thread(|| Ok((std::thread::current().id(), std::thread::current().name().map(String::from))));
        let mut seen = Vec::new();
        for threads in 1..4 {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let (caller, ran) = pool.install(|| (std::thread::current().id(), runner().unwrap()));
            assert_ne!(caller, ran.0);
            seen.push(ran);
        }
        assert!(seen.iter().all(|ran| *ran == seen[0]), "{seen:?}");
        assert_eq!(seen[0].1.as_deref(), Some(SOLVER_THREAD));
        let failed: ShapesmithResult<()> = on_solver_thread(|| panic!("a solve that panics"));
        assert!(matches!(failed, Err(ShapesmithError::Solver(_))));
        assert_eq!(runner().unwrap(), seen[0], "the thread survives a panicking job");
    }

    #[test]
    fn infeasible_is_reported_as_such() {
        let mut p = BinaryProgram::new(Sense::Minimise, vec![1.0, 1.0]);
        p.at_least(vec![(0, 1.0), (1, 1.0)], 3.0);
        assert!(matches!(solve_binary(&p, &IlpOptions::default()), Err(ShapesmithError::Infeasible(_))));
    }
}
