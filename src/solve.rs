//! The global sparse linear algebra: every faer call of the crate lives here.
//!
//! The stiffness (or effective dynamic stiffness) is stored as the lower
//! triangle of a CSC matrix on the free DOFs. The symbolic Cholesky
//! factorisation (AMD ordering, supernodal or simplicial as faer decides) is
//! computed once per pattern; each numeric factorisation reuses its `L`
//! buffer and scratch memory, so a time step allocates nothing.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::matmul::matmul;
use faer::linalg::triangular_solve::solve_lower_triangular_in_place;
use faer::perm::PermRef;
use faer::reborrow::{Reborrow, ReborrowMut};
use faer::sparse::linalg::cholesky::supernodal::{SupernodalLltRef, SymbolicSupernodalCholesky};
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, LltRef, SymbolicCholesky,
    SymbolicCholeskyRaw, SymmetricOrdering,
};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Accum, Conj, Mat, MatMut, Par, Side, Spec};

mod split;
pub use split::SplitCholesky;

#[derive(Debug, thiserror::Error)]
pub enum SolveError {
    #[error("symbolic factorisation failed: {0}")]
    Symbolic(String),
    #[error("the system matrix is not positive definite (a part may be free to move, or elements are degenerate)")]
    NotPositiveDefinite,
}

/// Lower-triangular CSC sparsity pattern of a symmetric matrix (rows sorted in each column).
#[derive(Debug, Clone, Default)]
pub struct Pattern {
    pub n: usize,
    pub col_ptr: Vec<usize>,
    pub row_idx: Vec<usize>,
}

impl Pattern {
    /// Builds the pattern from `(row, col)` entries with `row >= col` (duplicates allowed).
    pub fn from_entries(n: usize, cols: Vec<Vec<usize>>) -> Pattern {
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for mut rows in cols {
            rows.sort_unstable();
            rows.dedup();
            row_idx.extend_from_slice(&rows);
            col_ptr.push(row_idx.len());
        }
        Pattern {
            n,
            col_ptr,
            row_idx,
        }
    }

    pub fn nnz(&self) -> usize {
        self.row_idx.len()
    }

    /// Position of entry (row, col), row >= col, in the value array.
    pub fn position(&self, row: usize, col: usize) -> Option<usize> {
        let (lo, hi) = (self.col_ptr[col], self.col_ptr[col + 1]);
        self.row_idx[lo..hi]
            .binary_search(&row)
            .ok()
            .map(|k| lo + k)
    }

    fn symbolic(&self) -> SymbolicSparseColMatRef<'_, usize> {
        // SAFETY-free constructor: faer checks the invariants.
        SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx)
    }

    /// y += A x for the symmetric matrix whose lower triangle is `values`.
    pub fn sym_mul_add(&self, values: &[f64], x: &[f64], y: &mut [f64]) {
        for c in 0..self.n {
            let xc = x[c];
            let mut acc = 0.0;
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[k];
                let v = values[k];
                y[r] += v * xc;
                if r != c {
                    acc += v * x[r];
                }
            }
            y[c] += acc;
        }
    }
}

/// How many threads the numeric factorisation and the solves use (faer's
/// `Par`): one setting, passed in, for the whole solver.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Parallelism {
    threads: usize,
}

impl Parallelism {
    /// One thread (faer's `Par::Seq`).
    pub const SEQUENTIAL: Parallelism = Parallelism { threads: 1 };

    /// `threads` threads (0: rayon's current thread count).
    pub fn threads(threads: usize) -> Parallelism {
        let threads = if threads == 0 {
            rayon::current_num_threads()
        } else {
            threads
        };
        Parallelism { threads }
    }

    pub fn n_threads(self) -> usize {
        self.threads
    }

    /// `[f(0), …, f(n − 1)]`, computed by this many workers (the calling
    /// thread and tasks on rayon's pool) that each take the next index
    /// when done with the last: items of very different cost (a cut
    /// event's front elements hold 100× the quadrature points of their
    /// neighbours) balance. The order of the results, and each result,
    /// do not depend on the thread count.
    pub fn map<T: Send>(self, n: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
        let workers = self.threads.min(n);
        if workers <= 1 {
            return (0..n).map(f).collect();
        }
        let next = std::sync::atomic::AtomicUsize::new(0);
        let work = |part: &mut Vec<(usize, T)>| loop {
            let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            if i >= n {
                break;
            }
            part.push((i, f(i)));
        };
        let mut parts: Vec<Vec<(usize, T)>> = (0..workers).map(|_| Vec::new()).collect();
        rayon::scope(|s| {
            let (first, rest) = parts.split_at_mut(1);
            for part in rest {
                s.spawn(|_| work(part));
            }
            work(&mut first[0]);
        });
        let mut out: Vec<Option<T>> = (0..n).map(|_| None).collect();
        for (i, t) in parts.into_iter().flatten() {
            out[i] = Some(t);
        }
        // Every index below n was taken exactly once.
        out.into_iter().flatten().collect()
    }

    fn faer(self) -> Par {
        if self.threads <= 1 {
            Par::Seq
        } else {
            Par::rayon(self.threads)
        }
    }
}

impl Default for Parallelism {
    fn default() -> Self {
        Parallelism::SEQUENTIAL
    }
}

/// The fill-reducing ordering of the symbolic factorisation.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Ordering {
    /// faer's approximate minimum degree.
    #[default]
    Amd,
    /// A permutation given by the caller: `perm[new] = old` (e.g. nested dissection).
    Custom(Vec<usize>),
}

impl Ordering {
    /// Nested dissection of the matrix graph by METIS (`METIS_NodeND`), on
    /// the graph compressed by `blocks` (`blocks[eq]`: the block of equation
    /// eq, e.g. its node: the three DOFs of a node share their rows, and the
    /// compressed graph is nine times smaller); `None`: one block per equation.
    /// Within a block the equations keep their order.
    pub fn nested_dissection(
        pattern: &Pattern,
        blocks: Option<&[usize]>,
    ) -> Result<Ordering, SolveError> {
        if pattern.n == 0 {
            return Ok(Ordering::Custom(Vec::new()));
        }
        let graph = BlockGraph::new(pattern, blocks)?;
        let order = graph.nested_dissection()?;
        Ok(Ordering::Custom(graph.equations(&order)))
    }

    /// Nested dissection's first level alone: METIS's vertex separator of the
    /// graph compressed by `blocks` (`METIS_ComputeVertexSeparator`) splits
    /// the equations into two sides that do not couple and the separator;
    /// each side is then ordered by nested dissection (as
    /// [`Ordering::nested_dissection`]). `None` where a side is empty.
    pub fn separated(
        pattern: &Pattern,
        blocks: Option<&[usize]>,
    ) -> Result<Option<Separated>, SolveError> {
        if pattern.n == 0 {
            return Ok(None);
        }
        let graph = BlockGraph::new(pattern, blocks)?;
        let part = graph.separator()?;
        let mut sides = [Vec::new(), Vec::new()];
        for (p, side) in sides.iter_mut().enumerate() {
            let sub = graph.induced(&part, p as metis_sys::idx_t);
            if sub.graph.weight.is_empty() {
                return Ok(None);
            }
            let order: Vec<usize> = sub
                .graph
                .nested_dissection()?
                .into_iter()
                .map(|b| sub.blocks[b])
                .collect();
            *side = graph.equations(&order);
        }
        let separator: Vec<usize> = (0..part.len()).filter(|&b| part[b] == 2).collect();
        let separator = graph.equations(&separator);
        let [first, second] = sides;
        Ok(Some(Separated {
            sides: [first, second],
            separator,
        }))
    }
}

/// Nested dissection's first level ([`Ordering::separated`]): equations by
/// side (each in nested-dissection order) and the separator's. No equation
/// of one side couples with one of the other.
#[derive(Debug, Clone)]
pub struct Separated {
    pub sides: [Vec<usize>; 2],
    pub separator: Vec<usize>,
}

/// The matrix graph compressed by blocks of equations, in METIS's CSR form
/// (symmetric, no self-loops, 0-based), each block weighted by its equations.
struct BlockGraph {
    xadj: Vec<metis_sys::idx_t>,
    adjncy: Vec<metis_sys::idx_t>,
    weight: Vec<metis_sys::idx_t>,
    /// The equations of each block, in order (CSR).
    start: Vec<usize>,
    members: Vec<usize>,
}

/// A block graph's subgraph and the blocks of the whole its vertices are.
struct Induced {
    graph: BlockGraph,
    blocks: Vec<usize>,
}

fn too_big() -> SolveError {
    SolveError::Symbolic("the graph is too large for METIS's 32-bit indices".into())
}

impl BlockGraph {
    fn new(pattern: &Pattern, blocks: Option<&[usize]>) -> Result<BlockGraph, SolveError> {
        let n = pattern.n;
        let identity: Vec<usize>;
        let blocks = match blocks {
            Some(b) => {
                if b.len() != n {
                    return Err(SolveError::Symbolic(format!(
                        "{} blocks for a matrix of order {n}",
                        b.len()
                    )));
                }
                b
            }
            None => {
                identity = (0..n).collect();
                &identity
            }
        };
        let n_blocks = blocks.iter().max().map_or(0, |&b| b + 1);
        let mut adjacency: Vec<Vec<u32>> = vec![Vec::new(); n_blocks];
        let mut weight = vec![0 as metis_sys::idx_t; n_blocks];
        for c in 0..n {
            let bc = blocks[c];
            weight[bc] += 1;
            for &r in &pattern.row_idx[pattern.col_ptr[c]..pattern.col_ptr[c + 1]] {
                let br = blocks[r];
                if br != bc {
                    adjacency[br].push(bc as u32);
                    adjacency[bc].push(br as u32);
                }
            }
        }
        let mut xadj: Vec<metis_sys::idx_t> = Vec::with_capacity(n_blocks + 1);
        let mut adjncy: Vec<metis_sys::idx_t> = Vec::new();
        xadj.push(0);
        for list in &mut adjacency {
            list.sort_unstable();
            list.dedup();
            adjncy.extend(list.iter().map(|&b| b as metis_sys::idx_t));
            xadj.push(metis_sys::idx_t::try_from(adjncy.len()).map_err(|_| too_big())?);
        }
        drop(adjacency);
        let mut start = vec![0usize; n_blocks + 1];
        for &b in blocks {
            start[b + 1] += 1;
        }
        for b in 0..n_blocks {
            start[b + 1] += start[b];
        }
        let mut members = vec![0usize; n];
        let mut fill = start.clone();
        for (eq, &b) in blocks.iter().enumerate() {
            members[fill[b]] = eq;
            fill[b] += 1;
        }
        Ok(BlockGraph {
            xadj,
            adjncy,
            weight,
            start,
            members,
        })
    }

    /// The equations of `order`'s blocks, each block's in order.
    fn equations(&self, order: &[usize]) -> Vec<usize> {
        let mut out = Vec::with_capacity(
            order
                .iter()
                .map(|&b| self.start[b + 1] - self.start[b])
                .sum(),
        );
        for &b in order {
            out.extend_from_slice(&self.members[self.start[b]..self.start[b + 1]]);
        }
        out
    }

    /// `METIS_NodeND`: the blocks in elimination order.
    fn nested_dissection(&self) -> Result<Vec<usize>, SolveError> {
        let n = self.weight.len();
        let mut nvtxs = metis_sys::idx_t::try_from(n).map_err(|_| too_big())?;
        let (mut xadj, mut adjncy, mut weight) =
            (self.xadj.clone(), self.adjncy.clone(), self.weight.clone());
        let mut perm = vec![0 as metis_sys::idx_t; n];
        let mut iperm = vec![0 as metis_sys::idx_t; n];
        let mut options = [0 as metis_sys::idx_t; metis_sys::METIS_NOPTIONS as usize];
        // SAFETY: the arrays have the lengths METIS_NodeND reads and writes
        // (nvtxs + 1, xadj[nvtxs], nvtxs, NOPTIONS) and outlive the calls; the
        // graph is symmetric without self-loops, 0-based (the default numbering).
        let status = unsafe {
            metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr());
            metis_sys::METIS_NodeND(
                &mut nvtxs,
                xadj.as_mut_ptr(),
                adjncy.as_mut_ptr(),
                weight.as_mut_ptr(),
                options.as_mut_ptr(),
                perm.as_mut_ptr(),
                iperm.as_mut_ptr(),
            )
        };
        if status != metis_sys::rstatus_et_METIS_OK {
            return Err(SolveError::Symbolic(format!(
                "METIS_NodeND failed with status {status}"
            )));
        }
        Ok(perm.into_iter().map(|b| b as usize).collect())
    }

    /// `METIS_ComputeVertexSeparator`: each block's part, 0 or 1 (the sides)
    /// or 2 (the separator).
    fn separator(&self) -> Result<Vec<metis_sys::idx_t>, SolveError> {
        let n = self.weight.len();
        let mut nvtxs = metis_sys::idx_t::try_from(n).map_err(|_| too_big())?;
        let (mut xadj, mut adjncy, mut weight) =
            (self.xadj.clone(), self.adjncy.clone(), self.weight.clone());
        let mut part = vec![0 as metis_sys::idx_t; n];
        let mut sepsize: metis_sys::idx_t = 0;
        let mut options = [0 as metis_sys::idx_t; metis_sys::METIS_NOPTIONS as usize];
        // SAFETY: as in `nested_dissection`; `part` has nvtxs entries.
        let status = unsafe {
            metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr());
            metis_sys::METIS_ComputeVertexSeparator(
                &mut nvtxs,
                xadj.as_mut_ptr(),
                adjncy.as_mut_ptr(),
                weight.as_mut_ptr(),
                options.as_mut_ptr(),
                &mut sepsize,
                part.as_mut_ptr(),
            )
        };
        if status != metis_sys::rstatus_et_METIS_OK {
            return Err(SolveError::Symbolic(format!(
                "METIS_ComputeVertexSeparator failed with status {status}"
            )));
        }
        Ok(part)
    }

    /// The subgraph of the blocks in part `p` (their equations kept).
    fn induced(&self, part: &[metis_sys::idx_t], p: metis_sys::idx_t) -> Induced {
        let blocks: Vec<usize> = (0..part.len()).filter(|&b| part[b] == p).collect();
        let mut local = vec![usize::MAX; part.len()];
        for (l, &b) in blocks.iter().enumerate() {
            local[b] = l;
        }
        let mut xadj = Vec::with_capacity(blocks.len() + 1);
        let mut adjncy = Vec::new();
        let mut weight = Vec::with_capacity(blocks.len());
        let mut start = Vec::with_capacity(blocks.len() + 1);
        let mut members = Vec::new();
        xadj.push(0);
        start.push(0);
        for &b in &blocks {
            let neighbours = &self.adjncy[self.xadj[b] as usize..self.xadj[b + 1] as usize];
            adjncy.extend(
                neighbours
                    .iter()
                    .filter(|&&c| part[c as usize] == p)
                    .map(|&c| local[c as usize] as metis_sys::idx_t),
            );
            xadj.push(adjncy.len() as metis_sys::idx_t);
            weight.push(self.weight[b]);
            members.extend_from_slice(&self.members[self.start[b]..self.start[b + 1]]);
            start.push(members.len());
        }
        Induced {
            graph: BlockGraph {
                xadj,
                adjncy,
                weight,
                start,
                members,
            },
            blocks,
        }
    }
}

/// Entries of L from which the numeric factorisation and the solves run on
/// more than one thread (when asked to).
pub const PARALLEL_FACTOR_FROM: usize = 40_000_000;

/// What one update pair of the supernodal factorisation
/// ([`Cholesky::update_pairs`]) costs beyond its arithmetic, in the flops of
/// [`Cholesky::factor_flops`]. Fitted by least squares to faer's numeric
/// factorisation of the seed beam's corotational tangent on this project's
/// 2-core machine: 24 medians of 60 factorisations, the three candidates
/// taking turns (AMD, nested dissection on the shape and on the equation
/// graph), on 1080 Tet4 uncut, extended and tip-enriched, 2688 Tet4 uncut
/// and tip-enriched, 288 and 1080 Tet10 tip-enriched and 8640 Tet4 uncut
/// (`examples/ordering_cost.rs` prints the same): time ≈ 5.1e-8 ms ×
/// (flops + 31000 × pairs), within 13 % of each. At 1k Tet4 AMD makes about
/// half the pairs of nested dissection (180–228 against 480–580) and its
/// factorisation took 0.78–0.83 ms against 1.00–1.15 ms, though it fills
/// 2–5 % more. The solves are left out of the estimate: with 1–18 % more
/// entries, AMD's factors solved as fast at 1k Tet4 (fewer supernodes) and
/// within 1 % at 3.5k.
pub const UPDATE_PAIR_COST: f64 = 31_000.0;

/// Order from which [`Cholesky::fill_reducing`] takes nested dissection without comparing.
pub const NESTED_DISSECTION_FROM: usize = 10_000;

/// Order from which [`Cholesky::fill_reducing`] splits the factor on two
/// threads or more. The seed beam's corotational tangent (median of 21
/// numeric factorisations, split on 2 threads against the rule's whole
/// factor on 1): 840 equations 1.11 against 0.80 ms, 2160 equations 2.32
/// against 2.39 ms, 5460 (Tet10) 12.1 against 16.5 ms, 6552 (Tet4) 10.9
/// against 18.3 ms, 12852 (Tet10) 45 against 72 ms.
pub const SPLIT_FROM: usize = 4_000;

/// Sparse Cholesky LLᵀ with the symbolic analysis done once.
pub struct Cholesky {
    pattern: Pattern,
    factor: Factor,
    factored: bool,
    /// Number of numeric factorisations done (a work counter tests can pin).
    pub factorisations: usize,
    /// The fill-reducing ordering, in words (for [`Cholesky::describe`]).
    ordering: &'static str,
}

/// How the factor is held: faer's factorisation of the whole matrix, or two
/// halves on two threads and their separator ([`split::SplitCholesky`]).
enum Factor {
    Whole(Box<Whole>),
    Split(Box<SplitCholesky>),
}

struct Whole {
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    factor_mem: MemBuffer,
    solve_mem: MemBuffer,
    par: Par,
}

impl Cholesky {
    /// Symbolic factorisation of `pattern` (once per pattern), AMD ordering, one thread.
    pub fn new(pattern: &Pattern) -> Result<Cholesky, SolveError> {
        Cholesky::with(pattern, &Ordering::Amd, Parallelism::SEQUENTIAL)
    }

    /// Symbolic factorisation with the fill-reducing ordering chosen by the
    /// rule measured by `examples/ordering.rs` (the seed beam, Tet4 and
    /// Tet10, cut and uncut, 11k–180k DOFs): METIS nested dissection on the
    /// node graph (`blocks`) filled 10 % less than AMD at 11k free DOFs and
    /// 30–40 % less from 34k on, numeric factorisation 1.2–2.5× faster. So:
    /// from [`NESTED_DISSECTION_FROM`] equations on, nested dissection; below,
    /// AMD and nested dissection on the `blocks` graph and on the equation
    /// graph, keeping the one whose numeric factorisation is estimated to
    /// cost least ([`Cholesky::factor_cost`]: its flops and its supernodes'
    /// update pairs; the analyses are cheap there, and the factor is
    /// refactorised every Newton iteration). Until 2026-12-06 the rule kept
    /// the fewest entries in L; at 1k Tet4 that took nested dissection for
    /// 2–5 % fewer entries but twice the update pairs, and a factorisation
    /// 20–30 % slower than AMD's (`UPDATE_PAIR_COST`).
    /// The equation graph's dissection is the candidate that tip enrichment
    /// asked for: a tip node's twelve branch DOFs are four blocks of the
    /// shape graph, and its dissection filled the seed beam's factor with
    /// the front inside elements (`examples/step_profile.rs … tip`) by
    /// 168183 entries at 1k Tet4 against 141588 on the equation graph, and
    /// 2080269 against 1883691 at 10k (numeric factorisation 28.3 → 24.0
    /// ms; criterion's `tip/scene-step-corotational-tip` 62.6 → 57.8 ms at
    /// 10k, 5.76 → 5.62 ms at 1k); without a cut the two fill within 2 % of
    /// each other, and at 1k Tet10 the shape graph's stays the sparser.
    ///
    /// On two threads or more, from [`SPLIT_FROM`] equations on,
    /// the factor is split at nested dissection's first separator and its
    /// halves factorised side by side ([`Cholesky::split`]; faer's own
    /// threads share only the dense products inside a supernode). On the
    /// static benchmark meshes of 13k–55k DOFs, Tet4 and Tet10
    /// (`examples/split_factor.rs`), the numeric factorisation on two
    /// threads took 0.51–0.53 of the whole factor's time on one (medians of
    /// 5), the factors held −3 … +8 % entries, the ordering and symbolic
    /// factorisation took the same time.
    pub fn fill_reducing(
        pattern: &Pattern,
        blocks: Option<&[usize]>,
        parallelism: Parallelism,
    ) -> Result<Cholesky, SolveError> {
        if parallelism.n_threads() >= 2 && pattern.n >= SPLIT_FROM {
            if let Some(separated) = Ordering::separated(pattern, blocks)? {
                return Cholesky::split(pattern, &separated, parallelism);
            }
        }
        let mut best = Cholesky::nested_dissection(pattern, blocks, parallelism)?;
        if pattern.n >= NESTED_DISSECTION_FROM {
            return Ok(best);
        }
        if blocks.is_some() {
            let equations = Ordering::nested_dissection(pattern, None)?;
            let mut equations = Cholesky::with(pattern, &equations, parallelism)?;
            if equations.cheaper_than(&best) {
                equations.ordering = "METIS nested dissection on the equation graph";
                best = equations;
            }
        }
        let mut amd = Cholesky::with(pattern, &Ordering::Amd, parallelism)?;
        Ok(if !best.cheaper_than(&amd) {
            amd.ordering = "AMD ordering, the cheapest";
            amd
        } else {
            best
        })
    }

    /// Symbolic factorisation on METIS nested dissection of the graph
    /// compressed by `blocks` ([`Ordering::nested_dissection`]), named so.
    pub fn nested_dissection(
        pattern: &Pattern,
        blocks: Option<&[usize]>,
        parallelism: Parallelism,
    ) -> Result<Cholesky, SolveError> {
        let nd = Ordering::nested_dissection(pattern, blocks)?;
        let mut chol = Cholesky::with(pattern, &nd, parallelism)?;
        chol.ordering = if blocks.is_some() {
            "METIS nested dissection on the shape-function graph"
        } else {
            "METIS nested dissection"
        };
        Ok(chol)
    }

    /// Whether this factor's numeric factorisation is estimated to cost less
    /// than `other`'s: by [`Cholesky::factor_cost`] where both are
    /// supernodal, else by their entries.
    fn cheaper_than(&self, other: &Cholesky) -> bool {
        match (self.factor_cost(), other.factor_cost()) {
            (Some(a), Some(b)) => a < b,
            _ => self.factor_nnz() < other.factor_nnz(),
        }
    }

    /// Symbolic factorisation of `pattern` with `ordering`; the numeric
    /// factorisations and solves run with `parallelism`. Rebuild it when the
    /// pattern changes (DOFs added at a cut event).
    pub fn with(
        pattern: &Pattern,
        ordering: &Ordering,
        parallelism: Parallelism,
    ) -> Result<Cholesky, SolveError> {
        let par = parallelism.faer();
        let inverse;
        let faer_ordering = match ordering {
            Ordering::Amd => SymmetricOrdering::Amd,
            Ordering::Custom(perm) => {
                if perm.len() != pattern.n {
                    return Err(SolveError::Symbolic(format!(
                        "ordering of {} entries for a matrix of order {}",
                        perm.len(),
                        pattern.n
                    )));
                }
                let mut inv = vec![usize::MAX; perm.len()];
                for (new, &old) in perm.iter().enumerate() {
                    if old >= perm.len() || inv[old] != usize::MAX {
                        return Err(SolveError::Symbolic(
                            "the ordering is not a permutation".into(),
                        ));
                    }
                    inv[old] = new;
                }
                inverse = inv;
                SymmetricOrdering::Custom(PermRef::new_checked(perm, &inverse, perm.len()))
            }
        };
        let symbolic = factorize_symbolic_cholesky(
            pattern.symbolic(),
            Side::Lower,
            faer_ordering,
            CholeskySymbolicParams::default(),
        )
        .map_err(|e| SolveError::Symbolic(format!("{e:?}")))?;
        // faer's parallel numeric factorisation paid only for large factors
        // here (static solves on 2 cores, `refs/bench_static.py` and
        // `examples/static_profile.rs`: nnz(L) = 3.8M 77 → 135 ms, 24M and
        // 25M ±5 %, 81M 1.35× faster): below that size one thread.
        let par = if symbolic.len_val() < PARALLEL_FACTOR_FROM {
            Par::Seq
        } else {
            par
        };
        let factor_req = symbolic.factorize_numeric_llt_scratch::<f64>(par, Spec::default());
        let solve_req = symbolic.solve_in_place_scratch::<f64>(1, par);
        Ok(Cholesky {
            pattern: pattern.clone(),
            factor: Factor::Whole(Box::new(Whole {
                l_values: vec![0.0; symbolic.len_val()],
                symbolic,
                factor_mem: MemBuffer::new(factor_req),
                solve_mem: MemBuffer::new(solve_req),
                par,
            })),
            factored: false,
            factorisations: 0,
            ordering: match ordering {
                Ordering::Amd => "AMD ordering",
                Ordering::Custom(_) => "a given ordering",
            },
        })
    }

    /// Symbolic factorisation in two halves by `separated` (nested
    /// dissection's first level, [`Ordering::separated`]), factorised side by
    /// side on two threads ([`split::SplitCholesky`]); the separator's dense
    /// work runs on `parallelism`. Solves only whole (no halves).
    pub fn split(
        pattern: &Pattern,
        separated: &Separated,
        parallelism: Parallelism,
    ) -> Result<Cholesky, SolveError> {
        Ok(Cholesky {
            pattern: pattern.clone(),
            factor: Factor::Split(Box::new(SplitCholesky::new(
                pattern,
                separated,
                parallelism.faer(),
            )?)),
            factored: false,
            factorisations: 0,
            ordering: "nested dissection",
        })
    }

    /// One line on how the factor is held, for a run's report: its entries,
    /// and for a split one the separator and the sides.
    pub fn describe(&self) -> String {
        match &self.factor {
            Factor::Whole(_) => format!(
                "whole ({} equations, {} entries in L, {})",
                self.pattern.n,
                self.factor_nnz(),
                self.ordering
            ),
            Factor::Split(s) => {
                let [a, b] = s.side_lens();
                format!(
                    "split at nested dissection's first separator ({} equations) into halves of {a} and {b} equations factorised side by side ({} entries)",
                    s.separator_len(),
                    self.factor_nnz()
                )
            }
        }
    }

    /// Whether the factor is held in two halves ([`Cholesky::split`]).
    pub fn is_split(&self) -> bool {
        matches!(self.factor, Factor::Split(_))
    }

    /// The whole factor; panics on a split one (the halves' solves need
    /// [`Cholesky::has_halves`], which a split factor has not).
    fn whole(&self) -> &Whole {
        match &self.factor {
            Factor::Whole(w) => w,
            Factor::Split(_) => panic!("a whole factor"),
        }
    }

    fn whole_mut(&mut self) -> &mut Whole {
        match &mut self.factor {
            Factor::Whole(w) => w,
            Factor::Split(_) => panic!("a whole factor"),
        }
    }

    /// The pattern of the matrices this factorises.
    pub fn pattern(&self) -> &Pattern {
        &self.pattern
    }

    /// Number of non-zeros of the factor L (split: both halves' factors and
    /// the separator's dense one).
    pub fn factor_nnz(&self) -> usize {
        match &self.factor {
            Factor::Whole(w) => w.l_values.len(),
            Factor::Split(s) => s.factor_nnz(),
        }
    }

    /// Floating-point operations of one numeric factorisation (Σ over the
    /// columns of L of the squared count below the diagonal, plus the
    /// diagonal's), from the supernodal structure; None for a simplicial or
    /// split one.
    pub fn factor_flops(&self) -> Option<f64> {
        use faer::sparse::linalg::cholesky::SymbolicCholeskyRaw;
        let Factor::Whole(w) = &self.factor else {
            return None;
        };
        let SymbolicCholeskyRaw::Supernodal(s) = w.symbolic.raw() else {
            return None;
        };
        let begin = s.supernode_begin();
        let end = s.supernode_end();
        let rows = s.col_ptr_for_row_idx();
        let mut flops = 0.0;
        for k in 0..s.n_supernodes() {
            let w = end[k] - begin[k];
            let below = rows[k + 1] - rows[k];
            for j in 0..w {
                let c = (w - 1 - j + below) as f64;
                flops += c * c + c + 1.0;
            }
        }
        Some(flops)
    }

    /// The number of supernodes of a supernodal factor (None: simplicial or split).
    pub fn supernodes(&self) -> Option<usize> {
        self.supernodal().map(|s| s.n_supernodes())
    }

    /// The number of supernode pairs (d, s) where supernode d's columns
    /// update supernode s: what faer's left-looking numeric factorisation
    /// does one small dense product and scatter for. None for a simplicial
    /// or split factor.
    pub fn update_pairs(&self) -> Option<usize> {
        let s = self.supernodal()?;
        let (begin, end) = (s.supernode_begin(), s.supernode_end());
        let mut owner = vec![0; self.pattern.n];
        for k in 0..s.n_supernodes() {
            owner[begin[k]..end[k]].fill(k);
        }
        let (rows, idx) = (s.col_ptr_for_row_idx(), s.row_idx());
        // A supernode's rows below its diagonal block are sorted, so each
        // ancestor it updates is one run of equal owners.
        let pairs = (0..s.n_supernodes())
            .map(|k| {
                let below = &idx[rows[k]..rows[k + 1]];
                below
                    .iter()
                    .enumerate()
                    .filter(|&(i, &r)| i == 0 || owner[below[i - 1]] != owner[r])
                    .count()
            })
            .sum();
        Some(pairs)
    }

    /// The estimated cost of one numeric factorisation, in flops:
    /// [`Cholesky::factor_flops`] plus [`UPDATE_PAIR_COST`] per
    /// [`Cholesky::update_pairs`]. None for a simplicial or split factor.
    pub fn factor_cost(&self) -> Option<f64> {
        Some(self.factor_flops()? + UPDATE_PAIR_COST * self.update_pairs()? as f64)
    }

    /// Numeric factorisation of the matrix with the lower-triangle `values`.
    pub fn factorize(&mut self, values: &[f64]) -> Result<(), SolveError> {
        let p = &self.pattern;
        self.factored = false;
        match &mut self.factor {
            Factor::Whole(w) => {
                let a = SparseColMatRef::new(p.symbolic(), values);
                w.symbolic
                    .factorize_numeric_llt(
                        &mut w.l_values,
                        a,
                        Side::Lower,
                        LltRegularization::default(),
                        w.par,
                        MemStack::new(&mut w.factor_mem),
                        Spec::default(),
                    )
                    .map_err(|_| SolveError::NotPositiveDefinite)?;
                if w.l_values.iter().any(|v| !v.is_finite()) {
                    return Err(SolveError::NotPositiveDefinite);
                }
            }
            Factor::Split(s) => s.factorize(values)?,
        }
        self.factored = true;
        self.factorisations += 1;
        Ok(())
    }

    /// Factorises A + μ diag|A| for the smallest μ of 10⁻⁴, 10⁻³, …, 10² that
    /// is positive definite (`shifted`: scratch, resized to A's entries) and
    /// returns that μ, or `None` where none is: for a Newton matrix that is
    /// indefinite away from a stable equilibrium (buckling), the shifted one
    /// gives a descent direction that keeps the geometric softening.
    pub fn factorize_shifted(&mut self, values: &[f64], shifted: &mut Vec<f64>) -> Option<f64> {
        let mut mu = 1e-4;
        while mu <= 1e2 {
            shifted.clear();
            shifted.extend_from_slice(values);
            for c in 0..self.pattern.n {
                if let Some(at) = self.pattern.position(c, c) {
                    shifted[at] += mu * values[at].abs();
                }
            }
            if self.factorize(shifted).is_ok() {
                return Some(mu);
            }
            mu *= 10.0;
        }
        None
    }

    /// The diagonal of L of the last factorisation (the pivots, in the
    /// factor's order): supernodal blocks are column-major with the diagonal
    /// block on top, simplicial columns start with their diagonal.
    pub fn pivots(&self) -> Vec<f64> {
        assert!(self.factored, "pivots before a successful factorisation");
        let w = match &self.factor {
            Factor::Whole(w) => w,
            Factor::Split(s) => return s.pivots(),
        };
        let mut out = Vec::with_capacity(self.pattern.n);
        match w.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(sym) => {
                let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
                let at = sym.col_ptr_for_val();
                for s in 0..sym.n_supernodes() {
                    let ncols = end[s] - begin[s];
                    let nrows = (at[s + 1] - at[s]) / ncols;
                    out.extend((0..ncols).map(|k| w.l_values[at[s] + k * nrows + k]));
                }
            }
            SymbolicCholeskyRaw::Simplicial(sym) => {
                let col_ptr = sym.col_ptr();
                out.extend((0..self.pattern.n).map(|c| w.l_values[col_ptr[c]]));
            }
        }
        out
    }

    /// Solves A x = b in place (b ← x) with the last factorisation.
    pub fn solve_in_place(&mut self, b: &mut [f64]) {
        assert!(self.factored, "solve before a successful factorisation");
        let w = match &mut self.factor {
            Factor::Whole(w) => w,
            Factor::Split(s) => return s.solve_in_place(b),
        };
        let llt = LltRef::<usize, f64>::new(&w.symbolic, &w.l_values);
        let n = b.len();
        let rhs = MatMut::from_column_major_slice_mut(b, n, 1);
        llt.solve_in_place_with_conj(Conj::No, rhs, w.par, MemStack::new(&mut w.solve_mem));
    }

    /// The supernodal structure of L, if faer chose one (it does for all but
    /// small or very sparse factors): what the halved and sparse solves
    /// below need.
    fn supernodal(&self) -> Option<&SymbolicSupernodalCholesky<usize>> {
        let Factor::Whole(w) = &self.factor else {
            return None;
        };
        match w.symbolic.raw() {
            SymbolicCholeskyRaw::Supernodal(s) => Some(s),
            SymbolicCholeskyRaw::Simplicial(_) => None,
        }
    }

    /// Whether A = Pᵀ L Lᵀ P can be solved in halves ([`Cholesky::forward_in_place`],
    /// [`Cholesky::backward_in_place`], [`Cholesky::forward_sparse_columns`]).
    pub fn has_halves(&self) -> bool {
        self.supernodal().is_some()
    }

    /// xp = P b: xp\[i\] = b\[fwd\[i\]\] (the factor's order).
    pub fn permute_into(&self, b: &[f64], xp: &mut [f64]) {
        match self.whole().symbolic.perm() {
            Some(p) => {
                for (x, &f) in xp.iter_mut().zip(p.arrays().0) {
                    *x = b[f];
                }
            }
            None => xp.copy_from_slice(b),
        }
    }

    /// b = Pᵀ xp, the inverse of [`Cholesky::permute_into`].
    pub fn unpermute_from(&self, xp: &[f64], b: &mut [f64]) {
        match self.whole().symbolic.perm() {
            Some(p) => {
                for (&x, &f) in xp.iter().zip(p.arrays().0) {
                    b[f] = x;
                }
            }
            None => b.copy_from_slice(xp),
        }
    }

    /// The position of original row `r` in the factor's order.
    pub fn permuted_row(&self, r: usize) -> usize {
        self.whole().symbolic.perm().map_or(r, |p| p.arrays().1[r])
    }

    /// xp ← L⁻¹ xp (factor's order); allocates nothing. Panics without
    /// [`Cholesky::has_halves`].
    pub fn forward_in_place(&mut self, xp: &mut [f64]) {
        self.half_in_place(xp, false);
    }

    /// xp ← L⁻ᵀ xp (factor's order); allocates nothing. Panics without
    /// [`Cholesky::has_halves`].
    pub fn backward_in_place(&mut self, xp: &mut [f64]) {
        self.half_in_place(xp, true);
    }

    /// xp ← L⁻¹ xp, or L⁻ᵀ xp when `transpose`, on the solve scratch.
    fn half_in_place(&mut self, xp: &mut [f64], transpose: bool) {
        assert!(self.factored, "solve before a successful factorisation");
        let w = self.whole_mut();
        let SymbolicCholeskyRaw::Supernodal(sym) = w.symbolic.raw() else {
            panic!("supernodal factor");
        };
        let llt = SupernodalLltRef::<usize, f64>::new(sym, &w.l_values);
        let n = xp.len();
        let rhs = MatMut::from_column_major_slice_mut(xp, n, 1);
        let stack = MemStack::new(&mut w.solve_mem);
        if transpose {
            llt.l_transpose_solve_with_conj(Conj::No, rhs, w.par, stack);
        } else {
            llt.l_solve_with_conj(Conj::No, rhs, w.par, stack);
        }
    }

    /// Y ← L⁻¹ Y for `ncols` columns (n × ncols, column-major, factor's
    /// order) that have few non-zeros: only the supernodes the non-zeros
    /// reach (their elimination-tree ancestors) are visited, the others are
    /// left zero. `reached` (one flag per supernode) gets the supernodes
    /// visited added; [`Cholesky::reached_rows`] turns it into row ranges.
    /// For a cut event's coupling columns on the seed beam this visits about
    /// a quarter of the rows and 40 % of a full forward solve's work.
    pub fn forward_sparse_columns(&self, y: &mut [f64], ncols: usize, reached: &mut Vec<bool>) {
        assert!(self.factored, "solve before a successful factorisation");
        let sym = self.supernodal().expect("supernodal factor");
        let n = self.pattern.n;
        assert_eq!(y.len(), n * ncols, "n × ncols columns");
        let ns = sym.n_supernodes();
        reached.resize(ns, false);
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        let mut of = vec![0usize; n];
        for s in 0..ns {
            of[begin[s]..end[s]].fill(s);
        }
        let mut visit = vec![false; ns];
        for col in y.chunks_exact(n) {
            for (r, &v) in col.iter().enumerate() {
                if v != 0.0 {
                    visit[of[r]] = true;
                }
            }
        }
        let llt = SupernodalLltRef::<usize, f64>::new(sym, &self.whole().l_values);
        let mut x = MatMut::from_column_major_slice_mut(y, n, ncols);
        let mut tmp = Mat::<f64>::zeros(0, 0);
        for s in 0..ns {
            if !visit[s] {
                continue;
            }
            reached[s] = true;
            let node = llt.supernode(s);
            let l = node.val();
            let size = l.ncols();
            let (top, bottom) = l.split_at_row(size);
            let mut x_top = x.rb_mut().subrows_mut(node.start(), size);
            solve_lower_triangular_in_place(top, x_top.rb_mut(), Par::Seq);
            let pattern = node.pattern();
            tmp.resize_with(pattern.len(), ncols, |_, _| 0.0);
            matmul(
                tmp.as_mut(),
                Accum::Replace,
                bottom,
                x_top.rb(),
                1.0,
                Par::Seq,
            );
            for j in 0..ncols {
                for (i, &r) in pattern.iter().enumerate() {
                    x[(r, j)] -= tmp[(i, j)];
                }
            }
            for &r in pattern {
                visit[of[r]] = true;
            }
        }
    }

    /// The rows (factor's order) of the supernodes flagged in `reached`, as
    /// merged ranges (start, length).
    pub fn reached_rows(&self, reached: &[bool]) -> Vec<(usize, usize)> {
        let Some(sym) = self.supernodal() else {
            return vec![(0, self.pattern.n)];
        };
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        let mut ranges: Vec<(usize, usize)> = Vec::new();
        for (s, _) in reached.iter().enumerate().filter(|(_, &r)| r) {
            match ranges.last_mut() {
                Some((start, len)) if *start + *len == begin[s] => *len += end[s] - begin[s],
                _ => ranges.push((begin[s], end[s] - begin[s])),
            }
        }
        ranges
    }

    /// Solves A X = B in place for `ncols` right-hand sides at once (B
    /// column-major, n × ncols; B ← X), blocked: cheaper than `ncols` single
    /// solves. Allocates its scratch (for cut events, not steps).
    pub fn solve_columns_in_place(&mut self, b: &mut [f64], ncols: usize) {
        assert!(self.factored, "solve before a successful factorisation");
        assert_eq!(
            b.len(),
            self.pattern.n * ncols,
            "n × ncols right-hand sides"
        );
        let n = self.pattern.n;
        let w = match &mut self.factor {
            Factor::Whole(w) => w,
            Factor::Split(s) => {
                for column in b.chunks_exact_mut(n) {
                    s.solve_in_place(column);
                }
                return;
            }
        };
        let mut mem = MemBuffer::new(w.symbolic.solve_in_place_scratch::<f64>(ncols, w.par));
        let llt = LltRef::<usize, f64>::new(&w.symbolic, &w.l_values);
        let rhs = MatMut::from_column_major_slice_mut(b, n, ncols);
        llt.solve_in_place_with_conj(Conj::No, rhs, w.par, MemStack::new(&mut mem));
    }
}

/// Changes among old equations smaller than this, relative to the geometric
/// mean of their diagonals, are left out of a [`BorderedSolve`]'s border:
/// the round-off changes of the standard blocks of newly cut Tet4 (their
/// side volumes sum to the element's only to round-off).
pub const BORDER_TOLERANCE: f64 = 1e-13;

/// A bordered solve of a grown system on the factor of an earlier one
/// (METHODS.md, "Blades": reanalysis for growing cracks): what a linear
/// scene's steps solve with after cut events that only appended equations,
/// instead of refactorising.
///
/// After cut events without dropped DOFs the new matrix (equations of
/// `Model::update_cut`: the old ones keep their numbers, new ones are
/// appended) is A = A₀ + Δ with A₀ = blockdiag(A_old, D), D the diagonal
/// of A on the new equations, and
/// Δ = [[E, B], [Bᵀ, C − D]]: E the changes among old equations (the
/// enriched DOFs of the changed elements), B the coupling of the new
/// equations to the old ones, C their block. Δ = U W Uᵀ with
/// U = [P_E, B̂, P_N] (P_E the unit columns of E's equations, B̂ = [B; 0],
/// P_N those of the new equations) and W = [[E, 0, 0], [0, 0, I], [0, I, C − D]].
/// With Z = A₀⁻¹U (solves on the old factor, all columns of P_E and B̂ at
/// once, when the border is built; a border grown from the previous one on
/// the same factor solves only its new columns) and G = UᵀZ, A x = b is x = y − Z s,
/// y = A₀⁻¹b, (I + W G) s = W Uᵀy (Woodbury): one solve on the old factor,
/// two products with the n × k matrix Z and W and an LU solve of order k
/// per right-hand side, allocation-free. Without E (every change among old
/// equations within `tol`: the usual case of a growing extended front) the
/// border is the Schur complement of the new equations instead,
/// S = C − B A_old⁻¹ Bᵀ: x₂ = S⁻¹(b₂ − B y₁), x₁ = y₁ − A_old⁻¹Bᵀ x₂, one
/// product with an n_old × k_new matrix (half the Woodbury's columns).
/// On a supernodal factor the Schur border is kept in halves of the factor
/// instead ([`Forward`]): its set-up is a forward solve of sparse columns only.
#[derive(Clone)]
pub struct BorderedSolve {
    /// Columns of Z solved for when it was built (the others reused).
    solved: usize,
    n_old: usize,
    /// Old equations with changed entries among themselves (E's).
    changed: Vec<usize>,
    /// B̂'s columns: (old equation, value) per new equation.
    coupling: Vec<Vec<(usize, f64)>>,
    /// D on the new equations (index eq − n_old).
    diagonal: Vec<f64>,
    /// Z = A₀⁻¹U, n × k.
    z: nalgebra::DMatrix<f64>,
    w: nalgebra::DMatrix<f64>,
    /// LU of I + W G (none for an empty border or a Schur complement).
    lu: Option<nalgebra::LU<f64, nalgebra::Dyn, nalgebra::Dyn>>,
    /// Without changes among old equations (E = 0): the Cholesky factor of
    /// the Schur complement S = C − B A_old⁻¹ Bᵀ of the new equations.
    schur: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
    /// A Schur-complement border on a supernodal factor holds Y = L⁻¹ P Bᵀ
    /// in `z` instead of Z_B ([`Forward`]).
    forward: Option<Forward>,
    /// Scratch of order k: Uᵀy, then s.
    t: nalgebra::DVector<f64>,
    s: nalgebra::DVector<f64>,
}

/// The Schur-complement border in halves of A_old = Pᵀ L Lᵀ P: with
/// Y = L⁻¹ P Bᵀ (factor's order), S = C − Yᵀ Y, and a solve is
/// w = L⁻¹ P b₁, x₂ = S⁻¹ (b₂ − Yᵀ w), x₁ = Pᵀ L⁻ᵀ (w − Y x₂): the same two
/// triangular solves as Z_B's form, but Y is a forward solve only of
/// columns with a few non-zeros, which reaches only the supernodes above
/// them ([`Cholesky::forward_sparse_columns`]), and Y's products run over
/// those rows only.
#[derive(Clone)]
struct Forward {
    /// Supernodes Y's columns reach, and their rows as ranges.
    reached: Vec<bool>,
    rows: Vec<(usize, usize)>,
    /// G = Yᵀ Y (k_new × k_new), kept so that a grown border computes only
    /// its new columns.
    gram: nalgebra::DMatrix<f64>,
    /// Scratch of order n_old (factor's order).
    xp: Vec<f64>,
}

impl BorderedSolve {
    /// The bordered solve of the matrix `new_values` (lower CSC on `new`)
    /// on `chol`, factorised with `old_values` on `old`; `None` where the
    /// new system is smaller, where a new equation has no positive diagonal
    /// or where I + W G is singular or S not positive definite (refactorise
    /// then). The caller vouches
    /// that the old equations kept their numbers (no DOF dropped since
    /// `chol` was factorised). Changes among old equations with
    /// |A − A_old| ≤ `tol` × (the geometric mean of their diagonals) are
    /// left out of E (0: none; [`BORDER_TOLERANCE`]: round-off): the solve
    /// is then that of a matrix within `tol` of A.
    pub fn new(
        chol: &mut Cholesky,
        old: &Pattern,
        old_values: &[f64],
        new: &Pattern,
        new_values: &[f64],
        tol: f64,
    ) -> Option<BorderedSolve> {
        BorderedSolve::grown(None, chol, old, old_values, new, new_values, tol)
    }

    /// [`BorderedSolve::new`] reusing the columns of Z that `previous` (a
    /// border on the same factor, of an earlier matrix of the same growing
    /// system) solved for: a changed old equation's unit column always, a
    /// new equation's coupling column where its coupling is unchanged; only
    /// the others are solved on the factor.
    pub fn grown(
        previous: Option<&BorderedSolve>,
        chol: &mut Cholesky,
        old: &Pattern,
        old_values: &[f64],
        new: &Pattern,
        new_values: &[f64],
        tol: f64,
    ) -> Option<BorderedSolve> {
        BorderedSolve::grown_from(
            previous.cloned(),
            chol,
            old,
            old_values,
            new,
            new_values,
            tol,
        )
    }

    /// [`BorderedSolve::grown`] taking `previous` whole: a Schur-complement
    /// border whose new equations extend the previous one's keeps its Z
    /// (n_old × k) in place and appends the new columns, so an event
    /// neither copies nor zeroes the columns it reuses.
    pub fn grown_from(
        previous: Option<BorderedSolve>,
        chol: &mut Cholesky,
        old: &Pattern,
        old_values: &[f64],
        new: &Pattern,
        new_values: &[f64],
        tol: f64,
    ) -> Option<BorderedSolve> {
        BorderedSolve::grown_within(
            previous,
            chol,
            old,
            old_values,
            new,
            new_values,
            tol,
            usize::MAX,
        )
    }

    /// [`BorderedSolve::grown_from`] that gives up (`None`) before any
    /// solve on the factor when the border would be larger than
    /// `max_border` ([`BorderedSolve::border`]): an event that changed many
    /// old equations (a moved tip front) is refactorised without paying
    /// for the columns of a border it would not use.
    #[allow(clippy::too_many_arguments)]
    pub fn grown_within(
        previous: Option<BorderedSolve>,
        chol: &mut Cholesky,
        old: &Pattern,
        old_values: &[f64],
        new: &Pattern,
        new_values: &[f64],
        tol: f64,
        max_border: usize,
    ) -> Option<BorderedSolve> {
        let (n_old, n) = (old.n, new.n);
        if n < n_old {
            return None;
        }
        let previous = previous.filter(|p| p.n_old == n_old);
        let previous_ref = previous.as_ref();
        let k_new = n - n_old;
        let diagonal_of: Vec<f64> = (0..n)
            .map(|c| new.position(c, c).map_or(0.0, |p| new_values[p]))
            .collect();
        let diagonal = diagonal_of[n_old..].to_vec();
        if diagonal.iter().any(|&d| d <= 0.0 || !d.is_finite()) {
            return None;
        }
        let (mut e, mut c_minus_d) = (Vec::new(), Vec::new());
        let mut coupling = vec![Vec::new(); k_new];
        for c in 0..n {
            // The old column beside the new one (rows sorted in both).
            let (mut q, q_end) = if c < n_old {
                (old.col_ptr[c], old.col_ptr[c + 1])
            } else {
                (0, 0)
            };
            for p in new.col_ptr[c]..new.col_ptr[c + 1] {
                let (r, v) = (new.row_idx[p], new_values[p]);
                // Old entries gone from the new pattern.
                while q < q_end && old.row_idx[q] < r {
                    if old_values[q] != 0.0 {
                        e.push((old.row_idx[q], c, -old_values[q]));
                    }
                    q += 1;
                }
                match (r < n_old, c < n_old) {
                    (true, true) => {
                        let mut d = v;
                        if q < q_end && old.row_idx[q] == r {
                            d -= old_values[q];
                            q += 1;
                        }
                        let scale = (diagonal_of[r] * diagonal_of[c]).abs().sqrt();
                        if d != 0.0 && d.abs() > tol * scale {
                            e.push((r, c, d));
                        }
                    }
                    (false, true) => coupling[r - n_old].push((c, v)),
                    (false, false) => {
                        let d = if r == c { 0.0 } else { v };
                        if d != 0.0 {
                            c_minus_d.push((r - n_old, c - n_old, d));
                        }
                    }
                    (true, false) => unreachable!("lower triangle"),
                }
            }
            for q in q..q_end {
                if old_values[q] != 0.0 {
                    e.push((old.row_idx[q], c, -old_values[q]));
                }
            }
        }
        let mut changed: Vec<usize> = e.iter().flat_map(|&(r, c, _)| [r, c]).collect();
        changed.sort_unstable();
        changed.dedup();
        let s = changed.len();
        let k = s + 2 * k_new;
        if s == 0 && k_new > 0 {
            if k_new > max_border {
                return None;
            }
            return BorderedSolve::schur(previous, chol, n_old, coupling, diagonal, &c_minus_d);
        }
        if k > max_border {
            return None;
        }
        // Z's columns of a Schur border in halves are Y's, not A₀⁻¹U's.
        let previous_ref = previous_ref.filter(|p| p.forward.is_none());
        let slot = |eq: usize| changed.binary_search(&eq).expect("changed");
        let mut w = nalgebra::DMatrix::<f64>::zeros(k, k);
        for &(r, c, d) in &e {
            let (i, j) = (slot(r), slot(c));
            w[(i, j)] += d;
            if i != j {
                w[(j, i)] += d;
            }
        }
        for j in 0..k_new {
            w[(s + j, s + k_new + j)] = 1.0;
            w[(s + k_new + j, s + j)] = 1.0;
        }
        for &(r, c, d) in &c_minus_d {
            let (i, j) = (s + k_new + r, s + k_new + c);
            w[(i, j)] += d;
            if i != j {
                w[(j, i)] += d;
            }
        }
        // Z's columns of P_E and B̂: those `previous` has, and one blocked
        // solve on the old factor for the others.
        let m = s + k_new;
        let mut z = nalgebra::DMatrix::<f64>::zeros(n, k);
        let reused = |j: usize| -> Option<usize> {
            let p = previous_ref?;
            let ps = p.changed.len();
            if j < s {
                p.changed.binary_search(&changed[j]).ok()
            } else {
                let i = j - s;
                (i < p.coupling.len() && p.coupling[i] == coupling[i]).then_some(ps + i)
            }
        };
        let mut solve = Vec::new();
        for j in 0..m {
            match (reused(j), previous_ref) {
                (Some(pj), Some(p)) => z
                    .view_mut((0, j), (n_old, 1))
                    .copy_from(&p.z.view((0, pj), (n_old, 1))),
                _ => solve.push(j),
            }
        }
        if !solve.is_empty() && n_old > 0 {
            let mut cols = vec![0.0; n_old * solve.len()];
            for (&j, col) in solve.iter().zip(cols.chunks_exact_mut(n_old)) {
                if j < s {
                    col[changed[j]] = 1.0;
                } else {
                    for &(r, v) in &coupling[j - s] {
                        col[r] = v;
                    }
                }
            }
            chol.solve_columns_in_place(&mut cols, solve.len());
            for (&j, col) in solve.iter().zip(cols.chunks_exact(n_old)) {
                z.view_mut((0, j), (n_old, 1)).copy_from_slice(col);
            }
        }
        for j in 0..k_new {
            z[(n_old + j, s + k_new + j)] = 1.0 / diagonal[j];
        }
        let mut solver = BorderedSolve {
            solved: solve.len(),
            n_old,
            changed,
            coupling,
            diagonal,
            z,
            w,
            lu: None,
            schur: None,
            forward: None,
            t: nalgebra::DVector::zeros(k),
            s: nalgebra::DVector::zeros(k),
        };
        if k > 0 {
            let mut g = nalgebra::DMatrix::<f64>::zeros(k, k);
            let mut t = nalgebra::DVector::zeros(k);
            for j in 0..k {
                solver.border_of(solver.z.column(j).as_slice(), &mut t);
                g.set_column(j, &t);
            }
            let lu = (nalgebra::DMatrix::<f64>::identity(k, k) + &solver.w * g).lu();
            if !lu.is_invertible() {
                return None;
            }
            solver.lu = Some(lu);
        }
        Some(solver)
    }

    /// The Schur-complement border (no changes among old equations):
    /// Z_B = A_old⁻¹ Bᵀ (n_old × k_new) — or, on a supernodal factor,
    /// Y = L⁻¹ P Bᵀ and G = Yᵀ Y ([`Forward`]) — its leading columns taken from
    /// `previous` where its new equations are the same with the same
    /// coupling (its buffer kept, the rest appended and solved in place),
    /// and the Cholesky factor of S = C − B Z_B; `None` where S is not
    /// positive definite.
    fn schur(
        previous: Option<BorderedSolve>,
        chol: &mut Cholesky,
        n_old: usize,
        coupling: Vec<Vec<(usize, f64)>>,
        diagonal: Vec<f64>,
        c_minus_d: &[(usize, usize, f64)],
    ) -> Option<BorderedSolve> {
        let k_new = coupling.len();
        let halves = n_old > 0 && chol.has_halves();
        let mut data: Vec<f64> = Vec::new();
        let mut kept = 0;
        let mut reached = Vec::new();
        let mut gram_old = None;
        if let Some(p) = previous
            .filter(|p| p.schur.is_some() && p.z.nrows() == n_old && p.forward.is_some() == halves)
        {
            kept = p
                .coupling
                .iter()
                .zip(&coupling)
                .take_while(|(a, b)| a == b)
                .count();
            data = p.z.data.into();
            data.truncate(n_old * kept);
            if let Some(f) = p.forward {
                reached = f.reached;
                gram_old = Some(f.gram);
            }
        }
        data.resize(n_old * k_new, 0.0);
        for (col, c) in data[n_old * kept..]
            .chunks_exact_mut(n_old)
            .zip(&coupling[kept..])
        {
            for &(r, v) in c {
                col[if halves { chol.permuted_row(r) } else { r }] = v;
            }
        }
        if n_old > 0 && k_new > kept {
            if halves {
                chol.forward_sparse_columns(&mut data[n_old * kept..], k_new - kept, &mut reached);
            } else {
                chol.solve_columns_in_place(&mut data[n_old * kept..], k_new - kept);
            }
        }
        let z = nalgebra::DMatrix::from_vec(n_old, k_new, data);
        let mut schur = nalgebra::DMatrix::<f64>::zeros(k_new, k_new);
        for (i, &d) in diagonal.iter().enumerate() {
            schur[(i, i)] = d;
        }
        for &(r, c, d) in c_minus_d {
            schur[(r, c)] += d;
            if r != c {
                schur[(c, r)] += d;
            }
        }
        let forward = if halves {
            // G = Yᵀ Y: the kept block from `previous`, the new columns over
            // the rows Y reaches.
            let rows = chol.reached_rows(&reached);
            let mut gram = nalgebra::DMatrix::<f64>::zeros(k_new, k_new);
            if let Some(g) = gram_old {
                gram.view_mut((0, 0), (kept, kept))
                    .copy_from(&g.view((0, 0), (kept, kept)));
            }
            let m = k_new - kept;
            if m > 0 {
                let mut cols = nalgebra::DMatrix::<f64>::zeros(k_new, m);
                for &(start, len) in &rows {
                    cols.gemm_tr(
                        1.0,
                        &z.view((start, 0), (len, k_new)),
                        &z.view((start, kept), (len, m)),
                        1.0,
                    );
                }
                gram.view_mut((0, kept), (k_new, m)).copy_from(&cols);
                for j in kept..k_new {
                    for i in 0..kept {
                        gram[(j, i)] = gram[(i, j)];
                    }
                }
            }
            schur -= &gram;
            Some(Forward {
                reached,
                rows,
                gram,
                xp: vec![0.0; n_old],
            })
        } else {
            for (i, col) in coupling.iter().enumerate() {
                for j in 0..k_new {
                    schur[(i, j)] -= col.iter().map(|&(r, v)| v * z[(r, j)]).sum::<f64>();
                }
            }
            None
        };
        // Symmetric up to round-off: take its mean.
        let schur = (&schur + schur.transpose()) * 0.5;
        Some(BorderedSolve {
            solved: k_new - kept,
            n_old,
            changed: Vec::new(),
            coupling,
            diagonal,
            z,
            w: nalgebra::DMatrix::zeros(0, 0),
            lu: None,
            schur: Some(schur.cholesky()?),
            forward,
            t: nalgebra::DVector::zeros(k_new),
            s: nalgebra::DVector::zeros(k_new),
        })
    }

    /// t = Uᵀ x.
    fn border_of(&self, x: &[f64], t: &mut nalgebra::DVector<f64>) {
        let (s, k_new) = (self.changed.len(), self.coupling.len());
        for (i, &eq) in self.changed.iter().enumerate() {
            t[i] = x[eq];
        }
        for (j, col) in self.coupling.iter().enumerate() {
            t[s + j] = col.iter().map(|&(r, v)| v * x[r]).sum();
            t[s + k_new + j] = x[self.n_old + j];
        }
    }

    /// Size k of the border: the columns of Z a solve multiplies by (changed
    /// old, coupling and new equations; the new equations' coupling only,
    /// for a Schur complement).
    pub fn border(&self) -> usize {
        if self.schur.is_some() {
            self.coupling.len()
        } else {
            self.w.nrows()
        }
    }

    /// Whether this is a Schur-complement border in halves of the old
    /// factor ([`Forward`]: Y = L⁻¹ P Bᵀ instead of Z_B = A_old⁻¹ Bᵀ).
    pub fn in_halves(&self) -> bool {
        self.forward.is_some()
    }

    /// Columns of Z on the old factor: changed old equations + new ones.
    pub fn event_solves(&self) -> usize {
        self.changed.len() + self.coupling.len()
    }

    /// Those of [`BorderedSolve::event_solves`] solved when it was built
    /// (the others taken from the previous border, [`BorderedSolve::grown`]).
    pub fn solved_columns(&self) -> usize {
        self.solved
    }

    /// Solves A x = b in place (b ← x) on the old factor `chol`; allocates nothing.
    pub fn solve_in_place(&mut self, chol: &mut Cholesky, b: &mut [f64]) {
        let n_old = self.n_old;
        if let (Some(schur), Some(f)) = (&self.schur, self.forward.as_mut()) {
            let k_new = self.coupling.len();
            chol.permute_into(&b[..n_old], &mut f.xp);
            chol.forward_in_place(&mut f.xp);
            let mut x2 = self.t.rows_mut(0, k_new);
            x2.copy_from_slice(&b[n_old..]);
            for &(start, len) in &f.rows {
                let w = nalgebra::DVectorView::from_slice(&f.xp[start..start + len], len);
                x2.gemv_tr(-1.0, &self.z.view((start, 0), (len, k_new)), &w, 1.0);
            }
            schur.solve_mut(&mut x2);
            for &(start, len) in &f.rows {
                let mut w =
                    nalgebra::DVectorViewMut::from_slice(&mut f.xp[start..start + len], len);
                w.gemv(-1.0, &self.z.view((start, 0), (len, k_new)), &x2, 1.0);
            }
            chol.backward_in_place(&mut f.xp);
            chol.unpermute_from(&f.xp, &mut b[..n_old]);
            b[n_old..].copy_from_slice(x2.as_slice());
            return;
        }
        chol.solve_in_place(&mut b[..n_old]);
        if let Some(schur) = &self.schur {
            // x₂ = S⁻¹ (b₂ − B y₁), x₁ = y₁ − Z_B x₂.
            let k_new = self.coupling.len();
            let mut x2 = self.t.rows_mut(0, k_new);
            for (j, col) in self.coupling.iter().enumerate() {
                x2[j] = b[n_old + j] - col.iter().map(|&(r, v)| v * b[r]).sum::<f64>();
            }
            schur.solve_mut(&mut x2);
            b[n_old..].copy_from_slice(x2.as_slice());
            let mut x1 = nalgebra::DVectorViewMut::from_slice(&mut b[..n_old], n_old);
            x1.gemv(-1.0, &self.z.view((0, 0), (n_old, k_new)), &x2, 1.0);
            return;
        }
        for (x, d) in b[n_old..].iter_mut().zip(&self.diagonal) {
            *x /= d;
        }
        let Some(lu) = &self.lu else {
            return;
        };
        let mut t = std::mem::take(&mut self.t);
        self.border_of(b, &mut t);
        self.s.gemv(1.0, &self.w, &t, 0.0);
        self.t = t;
        // I + W G was checked invertible when built.
        lu.solve_mut(&mut self.s);
        let n = b.len();
        let mut x = nalgebra::DVectorViewMut::from_slice(b, n);
        x.gemv(-1.0, &self.z, &self.s, 1.0);
    }
}

/// Buffers of the preconditioned conjugate gradient (allocated once).
pub struct Pcg {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    q: Vec<f64>,
    /// Total CG iterations done (a work counter).
    pub iterations: usize,
}

impl Pcg {
    pub fn new(n: usize) -> Pcg {
        Pcg {
            r: vec![0.0; n],
            z: vec![0.0; n],
            p: vec![0.0; n],
            q: vec![0.0; n],
            iterations: 0,
        }
    }

    /// Solves A x = b (A: lower-triangle `values` on `pattern`), preconditioned by
    /// `precond` (z ← P⁻¹ z in place: e.g. the factorisation of a nearby
    /// matrix, a stale or warped tangent).
    /// `x` is overwritten, starting from zero. Returns whether ‖r‖ ≤ tol ‖b‖ was reached within `max_iterations`.
    #[allow(clippy::too_many_arguments)]
    pub fn solve(
        &mut self,
        pattern: &Pattern,
        values: &[f64],
        mut precond: impl FnMut(&mut [f64]),
        b: &[f64],
        x: &mut [f64],
        tol: f64,
        max_iterations: usize,
    ) -> bool {
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
        let b_norm = dot(b, b).sqrt();
        x.fill(0.0);
        if b_norm == 0.0 {
            return true;
        }
        self.r.copy_from_slice(b);
        self.z.copy_from_slice(b);
        precond(&mut self.z);
        self.p.copy_from_slice(&self.z);
        let mut rz = dot(&self.r, &self.z);
        for _ in 0..max_iterations {
            self.iterations += 1;
            self.q.fill(0.0);
            pattern.sym_mul_add(values, &self.p, &mut self.q);
            let pq = dot(&self.p, &self.q);
            if pq <= 0.0 || !pq.is_finite() {
                return false;
            }
            let alpha = rz / pq;
            for i in 0..x.len() {
                x[i] += alpha * self.p[i];
                self.r[i] -= alpha * self.q[i];
            }
            if dot(&self.r, &self.r).sqrt() <= tol * b_norm {
                return true;
            }
            self.z.copy_from_slice(&self.r);
            precond(&mut self.z);
            let rz_new = dot(&self.r, &self.z);
            let beta = rz_new / rz;
            rz = rz_new;
            for i in 0..x.len() {
                self.p[i] = self.z[i] + beta * self.p[i];
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parallel_map_keeps_the_order_whatever_the_threads() {
        // Items of very uneven cost, so the workers finish out of order.
        let f = |i: usize| -> (usize, f64) {
            let work = if i.is_multiple_of(7) { 20_000 } else { 10 };
            let s: f64 = (0..work).map(|k| ((i + k) as f64).sqrt()).sum();
            (i, s)
        };
        let serial: Vec<(usize, f64)> = (0..200).map(f).collect();
        for threads in [1, 2, 3, 8] {
            let p = Parallelism::threads(threads);
            assert_eq!(p.map(200, f), serial, "{threads} threads");
            assert!(p.map(0, f).is_empty());
            assert_eq!(p.map(1, f), vec![f(0)]);
        }
    }

    /// 1-D Laplacian with a Dirichlet end: tridiagonal SPD.
    fn laplacian(n: usize) -> (Pattern, Vec<f64>) {
        let cols = (0..n)
            .map(|c| if c + 1 < n { vec![c, c + 1] } else { vec![c] })
            .collect();
        let p = Pattern::from_entries(n, cols);
        let mut v = vec![0.0; p.nnz()];
        for c in 0..n {
            v[p.position(c, c).unwrap()] = 2.0;
            if c + 1 < n {
                v[p.position(c + 1, c).unwrap()] = -1.0;
            }
        }
        (p, v)
    }

    /// The pivots are L's diagonal: their squares multiply to det A, for a
    /// simplicial factor (the chain: det = n + 1) and a supernodal one
    /// (n I + J, J all ones: det = nⁿ⁻¹ · 2n).
    #[test]
    fn pivots_multiply_to_the_determinant() {
        let (p, v) = laplacian(30);
        let mut chol = Cholesky::new(&p).unwrap();
        chol.factorize(&v).unwrap();
        let log_det: f64 = chol.pivots().iter().map(|x| 2.0 * x.ln()).sum();
        assert!((log_det - 31f64.ln()).abs() <= 1e-12, "{log_det}");
        let n = 200;
        let p = Pattern::from_entries(n, (0..n).map(|c| (c..n).collect()).collect());
        let v: Vec<f64> = (0..n)
            .flat_map(|c| (c..n).map(move |r| if r == c { n as f64 + 1.0 } else { 1.0 }))
            .collect();
        let mut chol = Cholesky::new(&p).unwrap();
        chol.factorize(&v).unwrap();
        assert!(chol.has_halves(), "a dense matrix factorises supernodal");
        let pivots = chol.pivots();
        assert_eq!(pivots.len(), n);
        let log_det: f64 = pivots.iter().map(|x| 2.0 * x.ln()).sum();
        let nf = n as f64;
        let expected = (nf - 1.0) * nf.ln() + (2.0 * nf).ln();
        assert!(
            (log_det - expected).abs() <= 1e-10 * expected,
            "{log_det} vs {expected}"
        );
    }

    /// A chain grown at its end, 40 → 43 → 46 equations, solved bordered on
    /// the factor of the first: a simplicial factor, so the Schur border
    /// holds Z_B = A_old⁻¹ Bᵀ (the seed beam's supernodal ones, in halves,
    /// are checked in tests/blade.rs); grown from the previous border it
    /// solves only its new columns and equals the direct solve.
    #[test]
    fn a_schur_border_on_a_simplicial_factor_solves_the_grown_chain() {
        let (p0, v0) = laplacian(40);
        let mut chol = Cholesky::new(&p0).unwrap();
        chol.factorize(&v0).unwrap();
        assert!(!chol.has_halves());
        let mut previous = None;
        for n in [43, 46] {
            let (p, v) = laplacian(n);
            let mut bordered =
                BorderedSolve::grown_from(previous.take(), &mut chol, &p0, &v0, &p, &v, 0.0)
                    .unwrap();
            assert!(!bordered.in_halves());
            assert_eq!(bordered.border(), n - 40);
            // The three columns of the previous border are kept.
            assert_eq!(bordered.solved_columns(), 3);
            let b: Vec<f64> = (0..n).map(|i| (0.3 * i as f64).sin()).collect();
            let mut direct = Cholesky::new(&p).unwrap();
            direct.factorize(&v).unwrap();
            let (mut x, mut y) = (b.clone(), b.clone());
            direct.solve_in_place(&mut y);
            bordered.solve_in_place(&mut chol, &mut x);
            let diff = x
                .iter()
                .zip(&y)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(
                diff <= 1e-12 * y.iter().fold(0.0f64, |m, v| m.max(v.abs())),
                "{diff:e}"
            );
            previous = Some(bordered);
        }
    }

    #[test]
    fn cholesky_solves_and_refactorises_without_new_symbolic() {
        let n = 50;
        let (p, mut v) = laplacian(n);
        let mut chol = Cholesky::new(&p).unwrap();
        for scale in [1.0, 3.0] {
            for x in v.iter_mut() {
                *x *= scale;
            }
            chol.factorize(&v).unwrap();
            let x_true: Vec<f64> = (0..n).map(|i| (i as f64).sin()).collect();
            let mut b = vec![0.0; n];
            p.sym_mul_add(&v, &x_true, &mut b);
            chol.solve_in_place(&mut b);
            let err: f64 = b
                .iter()
                .zip(&x_true)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(err < 1e-10, "error {err}");
        }
        assert_eq!(chol.factorisations, 2);
    }

    #[test]
    fn indefinite_matrix_is_reported() {
        let (p, mut v) = laplacian(5);
        v[p.position(2, 2).unwrap()] = -4.0;
        let mut chol = Cholesky::new(&p).unwrap();
        assert!(matches!(
            chol.factorize(&v),
            Err(SolveError::NotPositiveDefinite)
        ));
    }

    /// 7-point Laplacian on a k³ grid with `dofs` unknowns per node
    /// (coupled node-wise), shifted to be SPD.
    fn grid(k: usize, dofs: usize) -> (Pattern, Vec<f64>) {
        let id = |x: usize, y: usize, z: usize| (x * k + y) * k + z;
        let n = k * k * k * dofs;
        let mut cols = vec![Vec::new(); n];
        for x in 0..k {
            for y in 0..k {
                for z in 0..k {
                    let a = id(x, y, z);
                    let mut nbrs = vec![a];
                    if x + 1 < k {
                        nbrs.push(id(x + 1, y, z));
                    }
                    if y + 1 < k {
                        nbrs.push(id(x, y + 1, z));
                    }
                    if z + 1 < k {
                        nbrs.push(id(x, y, z + 1));
                    }
                    for &b in &nbrs {
                        for i in 0..dofs {
                            for j in 0..dofs {
                                let (r, c) = (b * dofs + i, a * dofs + j);
                                if r >= c {
                                    cols[c].push(r);
                                }
                            }
                        }
                    }
                }
            }
        }
        let p = Pattern::from_entries(n, cols);
        let mut v = vec![-0.1; p.nnz()];
        for c in 0..n {
            v[p.position(c, c).unwrap()] = 7.0;
        }
        (p, v)
    }

    #[test]
    fn nested_dissection_is_a_permutation_that_solves_and_fills_less_than_amd() {
        let (p, v) = grid(16, 3);
        let blocks: Vec<usize> = (0..p.n).map(|eq| eq / 3).collect();
        let Ordering::Custom(perm) = Ordering::nested_dissection(&p, Some(&blocks)).unwrap() else {
            panic!("a custom ordering")
        };
        let mut seen = vec![false; p.n];
        for &old in &perm {
            assert!(!seen[old]);
            seen[old] = true;
        }
        // A node's three equations stay together, in order.
        for w in perm.chunks(3) {
            assert_eq!((w[1], w[2]), (w[0] + 1, w[0] + 2));
        }
        let amd = Cholesky::new(&p).unwrap();
        let mut nd = Cholesky::with(&p, &Ordering::Custom(perm), Parallelism::SEQUENTIAL).unwrap();
        println!(
            "16³ grid, 3 DOFs a node: nnz(L) AMD {}, METIS ND {}",
            amd.factor_nnz(),
            nd.factor_nnz()
        );
        assert!(nd.factor_nnz() < amd.factor_nnz());
        nd.factorize(&v).unwrap();
        let x_true: Vec<f64> = (0..p.n).map(|i| (i as f64 * 0.1).cos()).collect();
        let mut b = vec![0.0; p.n];
        p.sym_mul_add(&v, &x_true, &mut b);
        nd.solve_in_place(&mut b);
        let err = b
            .iter()
            .zip(&x_true)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-12, "error {err}");
    }

    /// The update pairs against L's structure found by elimination on the
    /// factor's order (each column's rows below the diagonal passed to its
    /// parent, the first of them), mapped to faer's supernodes: the
    /// distinct (supernode of column j, supernode of row i) with i below j
    /// in another supernode. AMD and nested dissection, 8³ grid, 3 DOFs a
    /// node; and the estimate is flops + UPDATE_PAIR_COST per pair.
    #[test]
    fn update_pairs_are_the_supernode_pairs_the_elimination_couples() {
        use std::collections::BTreeSet;
        let (p, _) = grid(8, 3);
        let nd = Ordering::nested_dissection(&p, None).unwrap();
        for ordering in [Ordering::Amd, nd] {
            let chol = Cholesky::with(&p, &ordering, Parallelism::SEQUENTIAL).unwrap();
            let n = p.n;
            let mut below = vec![BTreeSet::new(); n];
            for c in 0..n {
                for &r in &p.row_idx[p.col_ptr[c]..p.col_ptr[c + 1]] {
                    let (i, j) = (chol.permuted_row(r), chol.permuted_row(c));
                    if i != j {
                        below[i.min(j)].insert(i.max(j));
                    }
                }
            }
            for j in 0..n {
                let rows: Vec<usize> = below[j].iter().copied().collect();
                if let Some((&parent, rest)) = rows.split_first() {
                    below[parent].extend(rest.iter().copied());
                }
            }
            let s = chol.supernodal().expect("a supernodal factor");
            let mut owner = vec![usize::MAX; n];
            for k in 0..s.n_supernodes() {
                owner[s.supernode_begin()[k]..s.supernode_end()[k]].fill(k);
            }
            let pairs: BTreeSet<(usize, usize)> = (0..n)
                .flat_map(|j| below[j].iter().map(move |&i| (j, i)))
                .map(|(j, i)| (owner[j], owner[i]))
                .filter(|(a, b)| a != b)
                .collect();
            assert!(pairs.len() > s.n_supernodes(), "{}", pairs.len());
            assert_eq!(chol.update_pairs(), Some(pairs.len()));
            assert_eq!(chol.supernodes(), Some(s.n_supernodes()));
            let cost = chol.factor_flops().unwrap() + UPDATE_PAIR_COST * pairs.len() as f64;
            assert_eq!(chol.factor_cost(), Some(cost));
        }
    }

    #[test]
    fn the_first_separator_splits_the_equations_into_sides_that_do_not_couple() {
        let (p, _) = grid(16, 3);
        let blocks: Vec<usize> = (0..p.n).map(|eq| eq / 3).collect();
        let sep = Ordering::separated(&p, Some(&blocks)).unwrap().unwrap();
        let mut which = vec![usize::MAX; p.n];
        for (k, list) in [&sep.sides[0], &sep.sides[1], &sep.separator]
            .iter()
            .enumerate()
        {
            assert!(!list.is_empty());
            for &eq in *list {
                assert_eq!(which[eq], usize::MAX, "equation {eq} twice");
                which[eq] = k;
            }
        }
        assert!(which.iter().all(|&k| k != usize::MAX));
        for c in 0..p.n {
            for &r in &p.row_idx[p.col_ptr[c]..p.col_ptr[c + 1]] {
                let pair = (which[r].min(which[c]), which[r].max(which[c]));
                assert_ne!(pair, (0, 1), "({r}, {c}) couples the sides");
            }
        }
        // A node's equations stay together.
        assert!(sep.separator.chunks(3).all(|w| w[0] / 3 == w[2] / 3));
        // A 16³ grid's separator is a plane of nodes or so.
        assert!(
            sep.separator.len() <= 3 * 2 * 16 * 16,
            "{}",
            sep.separator.len()
        );
    }

    #[test]
    fn a_split_factor_solves_as_the_whole_one() {
        let (p, mut v) = grid(16, 3);
        // Stronger coupling than the grid's default, so that the separator's
        // Schur complement is far from its own block.
        for c in 0..p.n {
            for k in p.col_ptr[c]..p.col_ptr[c + 1] {
                if p.row_idx[k] != c {
                    v[k] = -0.3;
                }
            }
        }
        let blocks: Vec<usize> = (0..p.n).map(|eq| eq / 3).collect();
        let sep = Ordering::separated(&p, Some(&blocks)).unwrap().unwrap();
        let mut split = Cholesky::split(&p, &sep, Parallelism::threads(2)).unwrap();
        let nd = Ordering::nested_dissection(&p, Some(&blocks)).unwrap();
        let mut whole = Cholesky::with(&p, &nd, Parallelism::SEQUENTIAL).unwrap();
        assert!(split.is_split() && !whole.is_split() && !split.has_halves());
        split.factorize(&v).unwrap();
        whole.factorize(&v).unwrap();
        let x_true: Vec<f64> = (0..p.n).map(|i| (i as f64 * 0.1).cos()).collect();
        let mut b = vec![0.0; p.n];
        p.sym_mul_add(&v, &x_true, &mut b);
        let (mut xs, mut xw) = (b.clone(), b.clone());
        split.solve_in_place(&mut xs);
        whole.solve_in_place(&mut xw);
        let err = |x: &[f64], y: &[f64]| {
            x.iter()
                .zip(y)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max)
        };
        assert!(err(&xs, &x_true) < 1e-11, "{:e}", err(&xs, &x_true));
        assert!(err(&xs, &xw) < 1e-12, "{:e}", err(&xs, &xw));
        // Several columns solve each as one.
        let mut two = [b.clone(), b.iter().map(|v| -2.0 * v).collect()].concat();
        split.solve_columns_in_place(&mut two, 2);
        assert!(err(&two[..p.n], &xs) < 1e-14);
        assert!(
            err(
                &two[p.n..],
                &xs.iter().map(|v| -2.0 * v).collect::<Vec<_>>()
            ) < 1e-13
        );
        // One pivot per equation; their product is det A's square root in
        // both factors.
        let (ps, pw) = (split.pivots(), whole.pivots());
        assert_eq!(ps.len(), p.n);
        assert!(ps.iter().all(|&d| d > 0.0));
        let log_det = |d: &[f64]| d.iter().map(|v| v.ln()).sum::<f64>();
        assert!((log_det(&ps) - log_det(&pw)).abs() < 1e-9 * log_det(&pw).abs());
    }

    #[test]
    fn a_split_factor_solves_two_bodies_that_do_not_touch() {
        // Two grids side by side without coupling (a freed fragment): the
        // separator may be empty.
        let (g, gv) = grid(12, 3);
        let n = 2 * g.n;
        let mut cols = vec![Vec::new(); n];
        let mut v_of = std::collections::HashMap::new();
        for body in 0..2 {
            for c in 0..g.n {
                for k in g.col_ptr[c]..g.col_ptr[c + 1] {
                    let (r, cc) = (g.row_idx[k] + body * g.n, c + body * g.n);
                    cols[cc].push(r);
                    v_of.insert((r, cc), gv[k] * (1.0 + body as f64));
                }
            }
        }
        let p = Pattern::from_entries(n, cols);
        let mut v = vec![0.0; p.nnz()];
        for c in 0..n {
            for k in p.col_ptr[c]..p.col_ptr[c + 1] {
                v[k] = v_of[&(p.row_idx[k], c)];
            }
        }
        let blocks: Vec<usize> = (0..n).map(|eq| eq / 3).collect();
        let sep = Ordering::separated(&p, Some(&blocks)).unwrap().unwrap();
        println!("two bodies: separator of {} equations", sep.separator.len());
        let mut split = Cholesky::split(&p, &sep, Parallelism::threads(2)).unwrap();
        split.factorize(&v).unwrap();
        let x_true: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut b = vec![0.0; n];
        p.sym_mul_add(&v, &x_true, &mut b);
        split.solve_in_place(&mut b);
        let err = b
            .iter()
            .zip(&x_true)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(
            err < 1e-12,
            "separator {}: error {err:e}",
            sep.separator.len()
        );
    }

    #[test]
    fn a_nan_or_infinite_entry_anywhere_is_refused_by_every_factor() {
        // Off the diagonal, in the first column (its row's pivot is the only
        // one it reaches) and in the last but one; whole (simplicial and
        // supernodal) and split.
        let (p, v) = grid(12, 3);
        let blocks: Vec<usize> = (0..p.n).map(|eq| eq / 3).collect();
        let sep = Ordering::separated(&p, Some(&blocks)).unwrap().unwrap();
        let mut factors = [
            Cholesky::new(&p).unwrap(),
            Cholesky::fill_reducing(&p, Some(&blocks), Parallelism::SEQUENTIAL).unwrap(),
            Cholesky::split(&p, &sep, Parallelism::threads(2)).unwrap(),
        ];
        let (l3, _) = laplacian(6);
        let mut small = Cholesky::new(&l3).unwrap();
        assert!(!small.has_halves(), "a simplicial factor");
        let (_, lv) = laplacian(6);
        for bad in [f64::NAN, f64::INFINITY] {
            for col in [0, p.n - 2] {
                let k = p.col_ptr[col] + 1;
                assert!(p.row_idx[k] > col);
                let mut values = v.clone();
                values[k] = bad;
                for chol in &mut factors {
                    assert!(matches!(
                        chol.factorize(&values),
                        Err(SolveError::NotPositiveDefinite)
                    ));
                    chol.factorize(&v).unwrap();
                }
            }
            let mut values = lv.clone();
            let k = l3.col_ptr[0] + 1;
            values[k] = bad;
            assert!(matches!(
                small.factorize(&values),
                Err(SolveError::NotPositiveDefinite)
            ));
        }
    }

    #[test]
    fn a_split_factor_refuses_a_matrix_that_is_not_positive_definite() {
        let (p, v) = grid(16, 3);
        let blocks: Vec<usize> = (0..p.n).map(|eq| eq / 3).collect();
        let sep = Ordering::separated(&p, Some(&blocks)).unwrap().unwrap();
        let mut split = Cholesky::split(&p, &sep, Parallelism::threads(2)).unwrap();
        let mut whole =
            Cholesky::fill_reducing(&p, Some(&blocks), Parallelism::SEQUENTIAL).unwrap();
        // Indefinite in a side; then a separator's diagonal small enough
        // that the whole matrix is indefinite though each half is not
        // (≈ 0.02 − 0.014 > 0 on that equation): Σ's factorisation refuses it.
        for (eq, d) in [(sep.sides[1][100], -1.0), (sep.separator[4], 0.02)] {
            let mut bad = v.clone();
            bad[p.position(eq, eq).unwrap()] = d;
            assert!(whole.factorize(&bad).is_err());
            assert!(matches!(
                split.factorize(&bad),
                Err(SolveError::NotPositiveDefinite)
            ));
        }
        split.factorize(&v).unwrap();
        assert_eq!(split.factorisations, 1);
    }

    #[test]
    fn two_threads_split_the_factor_from_four_thousand_equations() {
        let (big, _) = grid(12, 3);
        let (small, _) = grid(10, 3);
        assert!(small.n < SPLIT_FROM && big.n >= SPLIT_FROM);
        let blocks = |p: &Pattern| (0..p.n).map(|eq| eq / 3).collect::<Vec<_>>();
        let two = Parallelism::threads(2);
        assert!(Cholesky::fill_reducing(&big, Some(&blocks(&big)), two)
            .unwrap()
            .is_split());
        assert!(
            !Cholesky::fill_reducing(&big, Some(&blocks(&big)), Parallelism::SEQUENTIAL)
                .unwrap()
                .is_split()
        );
        assert!(!Cholesky::fill_reducing(&small, Some(&blocks(&small)), two)
            .unwrap()
            .is_split());
    }

    #[test]
    fn a_custom_ordering_that_is_not_a_permutation_is_refused() {
        let (p, _) = laplacian(4);
        for perm in [vec![0, 1, 2], vec![0, 1, 1, 3], vec![0, 1, 2, 7]] {
            let r = Cholesky::with(&p, &Ordering::Custom(perm), Parallelism::SEQUENTIAL);
            assert!(matches!(r, Err(SolveError::Symbolic(_))));
        }
    }

    #[test]
    fn two_threads_factorise_as_one() {
        let (p, v) = grid(12, 3);
        let mut one = Cholesky::new(&p).unwrap();
        let mut two = Cholesky::with(&p, &Ordering::Amd, Parallelism::threads(2)).unwrap();
        one.factorize(&v).unwrap();
        two.factorize(&v).unwrap();
        let mut b1: Vec<f64> = (0..p.n).map(|i| (i as f64).sin()).collect();
        let mut b2 = b1.clone();
        one.solve_in_place(&mut b1);
        two.solve_in_place(&mut b2);
        let diff = b1
            .iter()
            .zip(&b2)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        let scale = b1.iter().map(|a| a.abs()).fold(0.0, f64::max);
        assert!(diff <= 1e-13 * scale, "{diff:e}");
    }
}
