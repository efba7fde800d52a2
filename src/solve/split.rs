//! A sparse Cholesky factorisation on two threads, split at nested
//! dissection's first separator.
//!
//! faer's supernodal factorisation runs its supernodes one after the other
//! (its threads only share the dense products inside a supernode, which pays
//! for large fronts alone). Nested dissection's first level splits the
//! equations into two sides that do not couple, A₁ and A₂, and the separator
//! S: K = [[A₁, 0, B₁], [0, A₂, B₂], [B₁ᵀ, B₂ᵀ, C]]. The principal submatrices
//! Kᵢ = [[Aᵢ, Bᵢ], [Bᵢᵀ, C]] of the positive definite K are positive definite;
//! each is factorised on its own thread with S last, Kᵢ = Lᵢ Lᵢᵀ,
//! Lᵢ = [[L_Aᵢ, 0], [Wᵢ, L_Sᵢ]], and the trailing block gives
//! L_Sᵢ L_Sᵢᵀ = C − Wᵢ Wᵢᵀ = C − Bᵢᵀ Aᵢ⁻¹ Bᵢ. The Schur complement of K on S
//! is then Σ = L_S₁ L_S₁ᵀ + L_S₂ L_S₂ᵀ − C, factorised dense (S is a
//! cross-section: small against the sides). A solve is forward on each side
//! (z = L_Aᵢ⁻¹ bᵢ, and gᵢ = Wᵢ z = Bᵢᵀ Aᵢ⁻¹ bᵢ read off the trailing part of
//! the same solve), x_S = Σ⁻¹(b_S − g₁ − g₂) and backward on each side with
//! L_Sᵢᵀ x_S in the trailing part, which leaves xᵢ = Aᵢ⁻¹(bᵢ − Bᵢ x_S).
//!
//! The separator's dense work is done three times (in each side's trailing
//! block, and in Σ), so this pays where S is small against the sides: the
//! slender bodies of the scenes (`Cholesky::fill_reducing` takes it on two
//! threads or more).

use super::{Pattern, Separated, SolveError};
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::linalg::cholesky::llt::factor::{cholesky_in_place, cholesky_in_place_scratch};
use faer::linalg::matmul::triangular::{matmul as tri_matmul, BlockStructure};
use faer::linalg::triangular_solve::{
    solve_lower_triangular_in_place, solve_upper_triangular_in_place,
};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::supernodal::SupernodalLltRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymbolicCholesky, SymbolicCholeskyRaw,
    SymmetricOrdering,
};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Accum, Conj, Mat, MatMut, Par, Side, Spec};

const NONE: usize = usize::MAX;

/// `n` zeros written one by one, so that the pages are mapped here (on the
/// thread that builds the symbolic factorisation, beside the model's
/// scatter maps) and not in the first numeric factorisation (the halves'
/// values, factors and scratch): on the 13k-DOF Tet10 static benchmark
/// (`examples/static_profile.rs`, 2 threads) the first numeric
/// factorisation took 26 ms instead of 35–41 (19.5 once warm).
fn touched(n: usize) -> Vec<f64> {
    let mut v = Vec::with_capacity(n);
    v.extend((0..n).map(|_| std::hint::black_box(0.0)));
    v
}

fn supernodal<'a>(
    symbolic: &'a SymbolicCholesky<usize>,
    l_values: &'a [f64],
) -> SupernodalLltRef<'a, usize, f64> {
    let SymbolicCholeskyRaw::Supernodal(sym) = symbolic.raw() else {
        unreachable!("the halves are forced supernodal")
    };
    SupernodalLltRef::new(sym, l_values)
}

/// One side: K restricted to its equations and the separator's, its own
/// first (in nested-dissection order), the separator's last.
struct Half {
    /// The equation of K of each local one.
    equations: Vec<usize>,
    /// Local equations of the side (the separator's follow).
    n_side: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// The position in K's values of each local entry.
    gather: Vec<usize>,
    values: Vec<f64>,
    symbolic: SymbolicCholesky<usize>,
    l_values: Vec<f64>,
    factor_mem: MemBuffer,
    solve_mem: MemBuffer,
    /// L_S, the trailing block of the factor (separator × separator, lower).
    trailing: Mat<f64>,
    /// Local right-hand side.
    rhs: Vec<f64>,
}

impl Half {
    fn new(pattern: &Pattern, side: &[usize], separator: &[usize]) -> Result<Half, SolveError> {
        let equations: Vec<usize> = side.iter().chain(separator).copied().collect();
        let n = equations.len();
        let mut local = vec![NONE; pattern.n];
        for (l, &g) in equations.iter().enumerate() {
            local[g] = l;
        }
        // Local lower triangle: an entry of K between two of the half's
        // equations goes to column min, row max of their local numbers.
        let mut col_ptr = vec![0usize; n + 1];
        let entries = |f: &mut dyn FnMut(usize, usize, usize)| {
            for c in 0..pattern.n {
                let lc = local[c];
                if lc == NONE {
                    continue;
                }
                for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                    let lr = local[pattern.row_idx[k]];
                    if lr != NONE {
                        f(lr.max(lc), lr.min(lc), k);
                    }
                }
            }
        };
        entries(&mut |_, col, _| col_ptr[col + 1] += 1);
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let nnz = col_ptr[n];
        let mut fill = col_ptr.clone();
        let mut placed = vec![(0usize, 0usize); nnz];
        entries(&mut |row, col, k| {
            placed[fill[col]] = (row, k);
            fill[col] += 1;
        });
        for c in 0..n {
            placed[col_ptr[c]..col_ptr[c + 1]].sort_unstable();
        }
        let row_idx: Vec<usize> = placed.iter().map(|&(r, _)| r).collect();
        let gather: Vec<usize> = placed.iter().map(|&(_, k)| k).collect();
        let structure = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        // The identity as a custom ordering: faer 0.24's `Identity` reads the
        // structure as an upper triangle whatever the side.
        let identity: Vec<usize> = (0..n).collect();
        let symbolic = factorize_symbolic_cholesky(
            structure,
            Side::Lower,
            SymmetricOrdering::Custom(PermRef::new_checked(&identity, &identity, n)),
            CholeskySymbolicParams {
                supernodal_flop_ratio_threshold: SupernodalThreshold::FORCE_SUPERNODAL,
                ..Default::default()
            },
        )
        .map_err(|e| SolveError::Symbolic(format!("{e:?}")))?;
        if symbolic
            .perm()
            .is_some_and(|p| p.arrays().0.iter().enumerate().any(|(i, &j)| i != j))
        {
            return Err(SolveError::Symbolic(
                "the split factorisation needs the halves in the given order".into(),
            ));
        }
        let mut factor_mem = MemBuffer::new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Spec::default()),
        );
        for byte in factor_mem.iter_mut().step_by(4096) {
            *byte = std::mem::MaybeUninit::new(0);
        }
        let solve_mem = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(1, Par::Seq));
        let n_sep = separator.len();
        Ok(Half {
            n_side: side.len(),
            equations,
            col_ptr,
            row_idx,
            gather,
            values: touched(nnz),
            l_values: touched(symbolic.len_val()),
            symbolic,
            factor_mem,
            solve_mem,
            trailing: Mat::zeros(n_sep, n_sep),
            rhs: vec![0.0; n],
        })
    }

    fn supernodal(&self) -> SupernodalLltRef<'_, usize, f64> {
        supernodal(&self.symbolic, &self.l_values)
    }

    /// Factorises the half of K's `values` and copies out L_S.
    fn factorize(&mut self, values: &[f64]) -> Result<(), SolveError> {
        for (v, &k) in self.values.iter_mut().zip(&self.gather) {
            *v = values[k];
        }
        let n = self.equations.len();
        let structure =
            SymbolicSparseColMatRef::new_checked(n, n, &self.col_ptr, None, &self.row_idx);
        self.symbolic
            .factorize_numeric_llt(
                &mut self.l_values,
                SparseColMatRef::new(structure, &self.values),
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut self.factor_mem),
                Spec::default(),
            )
            .map_err(|_| SolveError::NotPositiveDefinite)?;
        if self.l_values.iter().any(|v| !v.is_finite()) {
            return Err(SolveError::NotPositiveDefinite);
        }
        // The trailing block: the separator's columns of L, wherever their
        // supernodes begin (column-major, the dense diagonal block on top of
        // the rows below, all of which are the separator's).
        let s0 = self.n_side;
        let trailing = &mut self.trailing;
        trailing.fill(0.0);
        let llt = supernodal(&self.symbolic, &self.l_values);
        let sym = llt.symbolic();
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        for s in 0..sym.n_supernodes() {
            let (b, e) = (begin[s], end[s]);
            if e <= s0 {
                continue;
            }
            let node = llt.supernode(s);
            let (l, below) = (node.val(), node.pattern());
            let w = e - b;
            for j in b.max(s0)..e {
                for i in j..e {
                    trailing[(i - s0, j - s0)] = l[(i - b, j - b)];
                }
                for (p, &r) in below.iter().enumerate() {
                    trailing[(r - s0, j - s0)] = l[(w + p, j - b)];
                }
            }
        }
        Ok(())
    }

    /// Forward on the side's part of `b`: returns g = Bᵀ A⁻¹ b_side
    /// (into `g`), and keeps z = L_A⁻¹ b_side in `rhs`.
    fn forward(&mut self, b: &[f64], g: &mut [f64]) {
        let n = self.equations.len();
        for (x, &eq) in self.rhs.iter_mut().zip(&self.equations[..self.n_side]) {
            *x = b[eq];
        }
        self.rhs[self.n_side..].fill(0.0);
        supernodal(&self.symbolic, &self.l_values).l_solve_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut self.rhs, n, 1),
            Par::Seq,
            MemStack::new(&mut self.solve_mem),
        );
        // The trailing part holds w = L_S⁻¹(0 − W z), so W z = −L_S w.
        let w = &self.rhs[self.n_side..];
        for (i, gi) in g.iter_mut().enumerate() {
            let mut acc = 0.0;
            for (j, wj) in w.iter().enumerate().take(i + 1) {
                acc += self.trailing[(i, j)] * wj;
            }
            *gi = -acc;
        }
    }

    /// Backward with the separator's solution `xs`: leaves the side's
    /// solution in `rhs`' first `n_side` entries.
    fn backward(&mut self, xs: &[f64]) {
        let n = self.equations.len();
        // L_Sᵀ xs into the trailing part, so that the backward solve gives
        // xs there and A⁻¹(b − B xs) on the side.
        for (i, t) in self.rhs[self.n_side..].iter_mut().enumerate() {
            *t = (i..xs.len()).map(|j| self.trailing[(j, i)] * xs[j]).sum();
        }
        supernodal(&self.symbolic, &self.l_values).l_transpose_solve_with_conj(
            Conj::No,
            MatMut::from_column_major_slice_mut(&mut self.rhs, n, 1),
            Par::Seq,
            MemStack::new(&mut self.solve_mem),
        );
    }

    /// The diagonal of the side's columns of L.
    fn side_pivots(&self, out: &mut Vec<f64>) {
        let llt = self.supernodal();
        let sym = llt.symbolic();
        let (begin, end) = (sym.supernode_begin(), sym.supernode_end());
        for s in 0..sym.n_supernodes() {
            let (b, e) = (begin[s], end[s].min(self.n_side));
            let l = llt.supernode(s).val();
            out.extend((b..e).map(|k| l[(k - b, k - b)]));
        }
    }
}

/// K factorised in two halves on two threads and the separator's Schur
/// complement (see the module's text).
pub struct SplitCholesky {
    halves: [Half; 2],
    separator: Vec<usize>,
    /// C's lower entries: (row, column) in the separator, position in K.
    c_entries: Vec<(usize, usize, usize)>,
    /// Σ, then its Cholesky factor (lower).
    schur: Mat<f64>,
    schur_mem: MemBuffer,
    g: [Vec<f64>; 2],
    xs: Vec<f64>,
    par: Par,
}

impl SplitCholesky {
    /// The symbolic factorisations of the two halves of `pattern` by
    /// `separated` (which must separate: an entry of K between the two
    /// sides is refused); the separator's dense work runs on `par`.
    pub fn new(
        pattern: &Pattern,
        separated: &Separated,
        par: Par,
    ) -> Result<SplitCholesky, SolveError> {
        let n = pattern.n;
        let mut which = vec![NONE; n];
        for (p, side) in separated.sides.iter().enumerate() {
            for &eq in side {
                which[eq] = p;
            }
        }
        let mut sep_local = vec![NONE; n];
        for (l, &eq) in separated.separator.iter().enumerate() {
            which[eq] = 2;
            sep_local[eq] = l;
        }
        if which.contains(&NONE) {
            return Err(SolveError::Symbolic(
                "the split does not hold every equation once".into(),
            ));
        }
        let mut c_entries = Vec::new();
        for c in 0..n {
            for k in pattern.col_ptr[c]..pattern.col_ptr[c + 1] {
                let r = pattern.row_idx[k];
                match (which[r], which[c]) {
                    (0, 1) | (1, 0) => {
                        return Err(SolveError::Symbolic(
                            "the separator does not separate the two sides".into(),
                        ))
                    }
                    (2, 2) => {
                        let (i, j) = (sep_local[r], sep_local[c]);
                        c_entries.push((i.max(j), i.min(j), k));
                    }
                    _ => {}
                }
            }
        }
        let half = |side: &[usize]| Half::new(pattern, side, &separated.separator);
        let (first, second) =
            rayon::join(|| half(&separated.sides[0]), || half(&separated.sides[1]));
        let (first, second) = (first?, second?);
        let m = separated.separator.len();
        Ok(SplitCholesky {
            halves: [first, second],
            separator: separated.separator.clone(),
            c_entries,
            schur: Mat::zeros(m, m),
            schur_mem: MemBuffer::new(cholesky_in_place_scratch::<f64>(m, par, Spec::default())),
            g: [vec![0.0; m], vec![0.0; m]],
            xs: vec![0.0; m],
            par,
        })
    }

    /// Entries stored: both halves' factors and Σ's lower triangle.
    pub fn factor_nnz(&self) -> usize {
        let m = self.separator.len();
        self.halves.iter().map(|h| h.l_values.len()).sum::<usize>() + m * (m + 1) / 2
    }

    /// Equations of the separator.
    pub fn separator_len(&self) -> usize {
        self.separator.len()
    }

    /// Equations of each side (the separator's not counted).
    pub fn side_lens(&self) -> [usize; 2] {
        [self.halves[0].n_side, self.halves[1].n_side]
    }

    pub fn factorize(&mut self, values: &[f64]) -> Result<(), SolveError> {
        let [first, second] = &mut self.halves;
        let (a, b) = rayon::join(|| first.factorize(values), || second.factorize(values));
        a?;
        b?;
        // Σ = L_S₁ L_S₁ᵀ + L_S₂ L_S₂ᵀ − C, lower triangle.
        for (h, accum) in self.halves.iter().zip([Accum::Replace, Accum::Add]) {
            tri_matmul(
                self.schur.as_mut(),
                BlockStructure::TriangularLower,
                accum,
                h.trailing.as_ref(),
                BlockStructure::TriangularLower,
                h.trailing.transpose(),
                BlockStructure::TriangularUpper,
                1.0,
                self.par,
            );
        }
        for &(i, j, k) in &self.c_entries {
            self.schur[(i, j)] -= values[k];
        }
        cholesky_in_place(
            self.schur.as_mut(),
            LltRegularization::default(),
            self.par,
            MemStack::new(&mut self.schur_mem),
            Spec::default(),
        )
        .map_err(|_| SolveError::NotPositiveDefinite)?;
        let m = self.separator.len();
        if (0..m).any(|j| (j..m).any(|i| !self.schur[(i, j)].is_finite())) {
            return Err(SolveError::NotPositiveDefinite);
        }
        Ok(())
    }

    /// Solves K x = b in place with the last factorisation.
    pub fn solve_in_place(&mut self, b: &mut [f64]) {
        let [first, second] = &mut self.halves;
        let [g1, g2] = &mut self.g;
        let bb: &[f64] = b;
        rayon::join(|| first.forward(bb, g1), || second.forward(bb, g2));
        for (l, &eq) in self.separator.iter().enumerate() {
            self.xs[l] = b[eq] - self.g[0][l] - self.g[1][l];
        }
        let m = self.separator.len();
        let mut xs = MatMut::from_column_major_slice_mut(&mut self.xs, m, 1);
        solve_lower_triangular_in_place(self.schur.as_ref(), xs.as_mut(), Par::Seq);
        solve_upper_triangular_in_place(self.schur.transpose(), xs.as_mut(), Par::Seq);
        let xs: &[f64] = &self.xs;
        let [first, second] = &mut self.halves;
        rayon::join(|| first.backward(xs), || second.backward(xs));
        for h in &self.halves {
            for (x, &eq) in h.rhs.iter().zip(&h.equations[..h.n_side]) {
                b[eq] = *x;
            }
        }
        for (x, &eq) in self.xs.iter().zip(&self.separator) {
            b[eq] = *x;
        }
    }

    /// The pivots: the first side's, the second's, then Σ's factor's diagonal.
    pub fn pivots(&self) -> Vec<f64> {
        let mut out = Vec::new();
        for h in &self.halves {
            h.side_pivots(&mut out);
        }
        out.extend((0..self.separator.len()).map(|k| self.schur[(k, k)]));
        out
    }
}
