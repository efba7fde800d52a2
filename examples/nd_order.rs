//! Experiment: AMD against a graph nested dissection (BFS level separators)
//! as the fill-reducing ordering of the corotational 10k-tet beam.
mod common;

use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{
    factorize_symbolic_cholesky, CholeskySymbolicParams, SymmetricOrdering,
};
use faer::sparse::SymbolicSparseColMatRef;
use faer::{dyn_stack::MemBuffer, dyn_stack::MemStack, Par, Side, Spec};
use std::collections::VecDeque;
use std::time::Instant;
use xfem_cut::assembly::{evaluate, Request, Rotations, Workspace};

/// The allocator the `xfem-cut` binary and the benches run with (see
/// `src/main.rs`), so that what this times is what a run pays.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn adjacency(n: usize, col_ptr: &[usize], row_idx: &[usize]) -> Vec<Vec<usize>> {
    let mut adj = vec![Vec::new(); n];
    for c in 0..n {
        for &r in &row_idx[col_ptr[c]..col_ptr[c + 1]] {
            if r != c {
                adj[r].push(c);
                adj[c].push(r);
            }
        }
    }
    adj
}

/// BFS from `start` inside `mask == tag`; returns levels.
fn bfs(adj: &[Vec<usize>], start: usize, mask: &[u32], tag: u32, level: &mut [i32]) -> Vec<usize> {
    let mut order = vec![start];
    level[start] = 0;
    let mut q = VecDeque::from([start]);
    while let Some(v) = q.pop_front() {
        for &w in &adj[v] {
            if mask[w] == tag && level[w] < 0 {
                level[w] = level[v] + 1;
                order.push(w);
                q.push_back(w);
            }
        }
    }
    order
}

fn nd(
    adj: &[Vec<usize>],
    verts: Vec<usize>,
    mask: &mut [u32],
    next_tag: &mut u32,
    level: &mut [i32],
    out: &mut Vec<usize>,
) {
    if verts.len() <= 96 {
        out.extend(verts);
        return;
    }
    let tag = mask[verts[0]];
    // pseudo-peripheral start
    let mut start = verts[0];
    for _ in 0..3 {
        for &v in &verts {
            level[v] = -1;
        }
        start = *bfs(adj, start, mask, tag, level).last().unwrap();
    }
    for &v in &verts {
        level[v] = -1;
    }
    let reached = bfs(adj, start, mask, tag, level);
    let unreached: Vec<usize> = verts.iter().copied().filter(|&v| level[v] < 0).collect();
    let maxl = level[*reached.last().unwrap()];
    let half = reached.len() / 2;
    let mid = level[reached[half]];
    if maxl < 2 {
        out.extend(verts);
        return;
    }
    let (mut a, mut b, mut s) = (Vec::new(), Vec::new(), Vec::new());
    for &v in &reached {
        match level[v].cmp(&mid) {
            std::cmp::Ordering::Less => a.push(v),
            std::cmp::Ordering::Greater => b.push(v),
            std::cmp::Ordering::Equal => s.push(v),
        }
    }
    // Thin the separator: a separator vertex with no neighbour in b moves to a.
    let mut s2 = Vec::new();
    for &v in &s {
        if adj[v]
            .iter()
            .any(|&w| mask[w] == tag && level[w] == mid + 1)
        {
            s2.push(v);
        } else {
            a.push(v);
        }
    }
    for part in [a, b, unreached] {
        if part.is_empty() {
            continue;
        }
        *next_tag += 1;
        for &v in &part {
            mask[v] = *next_tag;
        }
        nd(adj, part, mask, next_tag, level, out);
    }
    for &v in &s2 {
        mask[v] = u32::MAX;
    }
    out.extend(s2);
}

fn main() {
    for div in [[6, 12, 24], [8, 16, 32], [3, 6, 11]] {
        let m = common::clamped_beam(div);
        let mut k = vec![0.0; m.pattern.nnz()];
        evaluate(
            &m,
            &vec![1e-3; m.n_dofs()],
            &mut Rotations::identity(&m),
            &mut Workspace::new(&m),
            Request {
                forces: None,
                tangent: Some(&mut k),
                update_rotations: true,
                exact_tangent: false,
            },
        );
        // diagonal shift like Newmark's mass term
        let p = &m.pattern;
        let n = p.n;
        for c in 0..n {
            let pos = p.position(c, c).unwrap();
            k[pos] *= 1.5;
        }
        let adj = adjacency(n, &p.col_ptr, &p.row_idx);
        let t = Instant::now();
        let mut mask = vec![0u32; n];
        let mut level = vec![-1i32; n];
        let mut order = Vec::with_capacity(n);
        let mut tag = 0;
        nd(
            &adj,
            (0..n).collect(),
            &mut mask,
            &mut tag,
            &mut level,
            &mut order,
        );
        let t_nd = t.elapsed();
        assert_eq!(order.len(), n);
        let mut inv = vec![0usize; n];
        for (i, &o) in order.iter().enumerate() {
            inv[o] = i;
        }
        let sym = SymbolicSparseColMatRef::new_checked(n, n, &p.col_ptr, None, &p.row_idx);
        for (name, ordering) in [
            ("amd", SymmetricOrdering::Amd),
            (
                "nd",
                SymmetricOrdering::Custom(PermRef::new_checked(&order, &inv, n)),
            ),
            (
                "nd-inv",
                SymmetricOrdering::Custom(PermRef::new_checked(&inv, &order, n)),
            ),
        ] {
            let t = Instant::now();
            let s = factorize_symbolic_cholesky(
                sym,
                Side::Lower,
                ordering,
                CholeskySymbolicParams::default(),
            )
            .unwrap();
            let ts = t.elapsed();
            let mut l = vec![0.0; s.len_val()];
            let mut mem =
                MemBuffer::new(s.factorize_numeric_llt_scratch::<f64>(Par::Seq, Spec::default()));
            let a = faer::sparse::SparseColMatRef::new(sym, &k);
            let mut best = f64::INFINITY;
            for _ in 0..7 {
                let t = Instant::now();
                s.factorize_numeric_llt(
                    &mut l,
                    a,
                    Side::Lower,
                    LltRegularization::default(),
                    Par::Seq,
                    MemStack::new(&mut mem),
                    Spec::default(),
                )
                .unwrap();
                best = best.min(t.elapsed().as_secs_f64());
            }
            println!("{div:?} n {n} {name}: nnz(L) {} symbolic {:?} numeric best {:.2} ms (nd order {:?})", s.len_val(), ts, best * 1e3, t_nd);
        }
    }
}
