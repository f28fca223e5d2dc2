//! The 0/1 programs solved on the conflict graph: one expression (Eq. (3) as a maximum-weight
//! independent set) and the fewest expressions possible (a graph colouring), plus the
//! first-fit colouring that serves as the greedy baseline and as the colouring's bound.

use super::conflicts::ConflictGraph;
use crate::error::{ShapesmithError, ShapesmithResult};
use crate::ilp::{solve_binary, BinaryProgram, IlpOptions, IlpSolution, Sense, SolveStatus};

/// Relative objective gap under which two expressions count as equally important: far
/// below the precision of importances computed from f32 displacements.
pub const TIE_TOLERANCE: f64 = 1e-10;

/// Solves; `None` when a time limit is set and HiGHS stopped before finding any point (it
/// then reports a failure rather than a status).
fn solve_within_limit(program: &BinaryProgram, options: &IlpOptions) -> ShapesmithResult<Option<IlpSolution>> {
    match solve_binary(program, options) {
        Err(ShapesmithError::Solver(_)) if options.time_limit.is_some() => Ok(None),
        other => other.map(Some),
    }
}

/// Eq. (3) on the nodes still `remaining`: maximise $\sum_v \lambda_v x_v$ subject to
/// $\sum_{v \in Q} x_v \le 1$ for every clique Q of the cover. Nodes with no remaining
/// neighbour are always taken (weights are positive) and stay out of the program; when the
/// rest is a set of disjoint cliques, the heaviest node of each is taken without a solve.
///
/// Ties (several sets of the same weight, common when shapes have equal importance) are
/// broken by a second solve: among the sets within [`TIE_TOLERANCE`] of the optimum, the one
/// whose nodes have the most remaining conflicts, so that hard-to-place shapes go early and
/// the loop needs fewer expressions. The primary optimum and its status come from the first
/// solve; if the second fails in any way, the first solution stands.
/// Returns the chosen nodes, ascending, and the first solve's status.
pub fn heaviest_independent_set(
    graph: &ConflictGraph,
    remaining: &[bool],
    weight: &[f64],
    options: &IlpOptions,
) -> ShapesmithResult<(Vec<usize>, SolveStatus)> {
    let n = graph.n_nodes();
    let mut chosen = Vec::new();
    let mut variable_of = vec![usize::MAX; n];
    let mut variables = Vec::new();
    for v in (0..n).filter(|&v| remaining[v]) {
        if (0..n).any(|u| remaining[u] && graph.adjacent[v][u]) {
            variable_of[v] = variables.len();
            variables.push(v);
        } else {
            chosen.push(v);
        }
    }
    let mut status = SolveStatus::Optimal;
    if !variables.is_empty() {
        let mut program = BinaryProgram::new(Sense::Maximise, variables.iter().map(|&v| weight[v]).collect());
        for clique in &graph.cliques {
            let terms: Vec<(usize, f64)> =
                clique.iter().filter(|&&v| remaining[v]).map(|&v| (variable_of[v], 1.0)).collect();
            if terms.len() >= 2 {
                program.at_most(terms, 1.0);
            }
        }
        let mut rows_per_variable = vec![0usize; variables.len()];
        for row in &program.rows {
            row.terms.iter().for_each(|t| rows_per_variable[t.0] += 1);
        }
        if rows_per_variable.iter().all(|&r| r == 1) {
            // The remaining conflicts are disjoint cliques (every edge lies in a row): the
            // heaviest node of each is optimal, and no solve is needed.
            for row in &program.rows {
                let heaviest = row.terms.iter().map(|t| variables[t.0]);
                chosen.extend(heaviest.max_by(|&a, &b| weight[a].total_cmp(&weight[b]).then(b.cmp(&a))));
            }
            chosen.sort_unstable();
            return Ok((chosen, SolveStatus::Optimal));
        }
        let Some(mut solution) = solve_within_limit(&program, options)? else {
            chosen.extend(complete_greedily(graph, &variables, Vec::new(), weight));
            chosen.sort_unstable();
            return Ok((chosen, SolveStatus::TimeLimit));
        };
        if solution.status.is_optimal() {
            if let Some(tied) = break_tie(graph, remaining, &variables, &program, weight, solution.objective, options) {
                solution = IlpSolution { status: solution.status, ..tied };
            }
        }
        status = solution.status;
        let solved: Vec<usize> = variables.iter().zip(&solution.x).filter(|p| *p.1).map(|p| *p.0).collect();
        if status.is_optimal() {
            chosen.extend(solved);
        } else {
            // Stopped early: whatever HiGHS found, made maximal, so the expression is never
            // empty and the loop always ends.
            chosen.extend(complete_greedily(graph, &variables, solved, weight));
        }
    }
    chosen.sort_unstable();
    Ok((chosen, status))
}

/// Among the sets within [`TIE_TOLERANCE`] of the optimum `best`, the one whose nodes have
/// the most conflicts among the remaining nodes; `None` if that solve fails in any way.
fn break_tie(
    graph: &ConflictGraph,
    remaining: &[bool],
    variables: &[usize],
    program: &BinaryProgram,
    weight: &[f64],
    best: f64,
    options: &IlpOptions,
) -> Option<IlpSolution> {
    let conflicts = |v: usize| (0..graph.n_nodes()).filter(|&u| remaining[u] && graph.adjacent[v][u]).count() as f64;
    let mut tie_break = BinaryProgram::new(Sense::Maximise, variables.iter().map(|&v| conflicts(v)).collect());
    tie_break.rows = program.rows.clone();
    tie_break.at_least(
        variables.iter().enumerate().map(|(i, &v)| (i, weight[v])).collect(),
        best - TIE_TOLERANCE * best.max(1.0),
    );
    solve_binary(&tie_break, options).ok()
}

/// Adds to `taken` every candidate, heaviest first, that conflicts with nothing taken.
fn complete_greedily(graph: &ConflictGraph, candidates: &[usize], mut taken: Vec<usize>, weight: &[f64]) -> Vec<usize> {
    let mut order = candidates.to_vec();
    order.sort_by(|&a, &b| weight[b].total_cmp(&weight[a]).then(a.cmp(&b)));
    for v in order {
        if !taken.contains(&v) && taken.iter().all(|&u| !graph.adjacent[u][v]) {
            taken.push(v);
        }
    }
    taken
}

/// First-fit colouring: each node, in the given order, joins the first group holding no
/// neighbour, or opens a new one. With nodes ordered by importance this is the greedy
/// packer; its group count bounds the fewest expressions from above.
pub fn first_fit(graph: &ConflictGraph, order: &[usize]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for &v in order {
        match groups.iter_mut().find(|g| g.iter().all(|&u| !graph.adjacent[u][v])) {
            Some(group) => group.push(v),
            None => groups.push(vec![v]),
        }
    }
    groups
}

/// The fewest expressions for the graph (its chromatic number) as a 0/1 program with at most
/// `colours` colours (an upper bound from a known colouring): $x_{v,c}$ node v takes colour
/// c, $y_c$ colour c is used; minimise $\sum_c y_c$ s.t. $\sum_c x_{v,c} = 1$,
/// $\sum_{v \in Q} x_{v,c} \le y_c$ for every clique Q and colour c, and $y_c \ge y_{c+1}$.
/// The largest clique of the cover is pre-coloured 0, 1, 2, ... (any colouring can be
/// relabelled so), which removes most symmetric copies of every solution.
/// Returns the count and the status.
pub fn fewest_colours(graph: &ConflictGraph, colours: usize, options: &IlpOptions) -> ShapesmithResult<(usize, SolveStatus)> {
    let n = graph.n_nodes();
    if n == 0 {
        return Ok((0, SolveStatus::Optimal));
    }
    if graph.cliques.is_empty() || colours <= 1 {
        return Ok((1, SolveStatus::Optimal));
    }
    let largest = graph.cliques.iter().max_by_key(|q| q.len()).map_or(&[][..], |q| &q[..]);
    if largest.len() >= colours {
        // A clique needs as many colours as the known colouring uses: it is optimal.
        return Ok((colours, SolveStatus::Optimal));
    }
    let x = |v: usize, c: usize| v * colours + c;
    let y = |c: usize| n * colours + c;
    let mut objective = vec![0.0; n * colours + colours];
    for c in 0..colours {
        objective[y(c)] = 1.0;
    }
    let mut program = BinaryProgram::new(Sense::Minimise, objective);
    for v in 0..n {
        program.equal((0..colours).map(|c| (x(v, c), 1.0)).collect(), 1.0);
    }
    let mut in_clique = vec![false; n];
    for clique in &graph.cliques {
        for c in 0..colours {
            let mut terms: Vec<(usize, f64)> = clique.iter().map(|&v| (x(v, c), 1.0)).collect();
            terms.push((y(c), -1.0));
            program.at_most(terms, 0.0);
        }
        for &v in clique {
            in_clique[v] = true;
        }
    }
    for v in (0..n).filter(|&v| !in_clique[v]) {
        for c in 0..colours {
            program.at_most(vec![(x(v, c), 1.0), (y(c), -1.0)], 0.0);
        }
    }
    for c in 0..colours - 1 {
        program.at_least(vec![(y(c), 1.0), (y(c + 1), -1.0)], 0.0);
    }
    for (c, &v) in largest.iter().enumerate() {
        program.equal(vec![(x(v, c), 1.0)], 1.0);
    }
    let Some(solution) = solve_within_limit(&program, options)? else {
        // No point found in time: the known colouring is the best count available.
        return Ok((colours, SolveStatus::TimeLimit));
    };
    let used = (0..colours).filter(|&c| solution.x[y(c)]).count();
    Ok((used, solution.status))
}

