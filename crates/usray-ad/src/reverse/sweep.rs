//! The reverse sweep: each node's adjoint pushed to its parents, from the
//! latest output down to the inputs.

use super::tape::Node;

/// The reverse sweep: nodes `top, top−1, …, lo + 1`, each pushing its adjoint
/// to its parents (nodes `1..=lo` must be inputs: they have none, and pushing
/// their zero partials to the dummy node would chain every step through the
/// same memory slot). A zero adjoint is not propagated (so an infinite partial on a
/// branch that does not reach the output gives 0, not `0·∞ = NaN`), and zero
/// partials were redirected to the dummy node when recorded: `0·∞ = 0`, the
/// convention of [`crate::Dual`], so both modes agree at singular points.
#[inline]
pub(super) fn sweep(nodes: &[Node], adj: &mut [f64], top: usize, lo: usize) {
    // `adj.len()` is a power of two above `top`: indexing with `& mask` is then
    // provably in bounds, so the loop carries no bounds checks (and no `unsafe`).
    // Every parent index is below its child, so the mask never changes an index.
    let size = adj.len();
    assert!(size.is_power_of_two() && top < size);
    let mask = size - 1;
    let nodes = &nodes[..=top];
    // A `while` loop: `(1..=top).rev()` (an inclusive range) compiles to a
    // noticeably slower loop.
    //
    // Many nodes feed the node recorded just before them; going through memory
    // for that edge puts a store-to-load forward on the critical path of the
    // next step. That contribution is carried in a register instead (`carry`).
    // (Branching around `adj[i] + carry` when only the carry reached node i,
    // to shorten the chain further, measured no faster.)
    let mut i = top;
    let mut carry = 0.0;
    while i > lo {
        let g = adj[i & mask] + carry;
        adj[i & mask] = g;
        carry = if g != 0.0 {
            propagate(nodes[i], i, g, adj, mask)
        } else {
            0.0
        };
        i -= 1;
    }
    // What the last node processed passed on to node `lo` (an input).
    if carry != 0.0 {
        adj[lo & mask] += carry;
    }
}

/// Push the adjoint `g` of node `i` to its parents; returns the part destined
/// for node `i − 1` (kept in a register by the caller, see [`sweep`]).
#[inline(always)]
fn propagate(n: Node, i: usize, g: f64, adj: &mut [f64], mask: usize) -> f64 {
    let (ca, cb) = (g * n.da, g * n.db);
    let prev = (i - 1) as u32;
    let (a_next, b_next) = (n.a == prev, n.b == prev);
    if !a_next {
        adj[n.a as usize & mask] += ca;
    }
    if !b_next {
        adj[n.b as usize & mask] += cb;
    }
    // No `ca + 0.0` on the common path: that add would sit on the critical
    // path (carry → add → multiply → carry) of every step.
    match (a_next, b_next) {
        (true, true) => ca + cb,
        (true, false) => ca,
        (false, true) => cb,
        (false, false) => 0.0,
    }
}
