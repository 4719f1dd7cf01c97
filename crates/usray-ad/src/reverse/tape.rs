//! The per-thread tape (its nodes and buffers, held by a thread-local) and the
//! recording ids that tell whether a [`Var`](super::Var) belongs to the
//! recording live on this thread.

use core::cell::{Cell, RefCell};
use core::sync::atomic::{AtomicU32, Ordering as AtomicOrdering};

/// One tape entry: `adj[a] += adj[self]·da`, `adj[b] += adj[self]·db`.
/// Every node recorded by an operation has two parents (unary steps record
/// none, see [`Var`](super::Var)'s scale); an edge with a zero partial points
/// at the dummy node 0, and input nodes point both at 0. This keeps the reverse
/// sweep free of branches on arity.
#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    pub(super) a: u32,
    pub(super) b: u32,
    pub(super) da: f64,
    pub(super) db: f64,
}

pub(super) const DUMMY: Node = Node {
    a: 0,
    b: 0,
    da: 0.0,
    db: 0.0,
};

/// The per-thread tape (the ids of the live recording are in [`LIVE`]).
pub(super) struct Tape {
    pub(super) nodes: Vec<Node>,
    pub(super) inputs: Vec<u32>,
    pub(super) adj: Vec<f64>,
    /// Lengths of `nodes` and `inputs` at
    /// [`Recording::freeze`](super::Recording::freeze) (what
    /// [`Recording::rewind`](super::Recording::rewind) keeps); 0 when not frozen.
    pub(super) frozen: (usize, usize),
}

thread_local! {
    /// This thread's tape. The tape itself is leaked (`Box::leak`) so that this
    /// thread-local holds only a `Copy` reference and needs no destructor: access
    /// is then a plain thread-pointer load the compiler inlines into every
    /// operation (a thread-local with a destructor went through an out-of-line
    /// `LocalKey::with` per operation, ~3× slower). The buffers are freed at
    /// thread exit by [`TapeRelease`]; only the empty header (≈ 100 bytes) stays
    /// leaked per thread that ever used reverse mode.
    static TAPE: Cell<Option<&'static RefCell<Tape>>> = const { Cell::new(None) };
    /// Frees this thread's tape buffers when the thread exits.
    static RELEASE: TapeRelease = const { TapeRelease };
    /// Ids of the recording live on this thread: `(current, frozen)`, both 0
    /// if none. `Var`s recorded now carry the current id; those made before
    /// [`Recording::freeze`](super::Recording::freeze) carry the frozen id (0
    /// when not frozen, which no non-constant `Var` carries). Kept outside the
    /// tape so that checking a `Var` is one thread-local load, with no borrow.
    pub(super) static LIVE: Cell<(u32, u32)> = const { Cell::new((0, 0)) };
}

/// Ids of the recording live on this thread, `(current, frozen)` (see [`LIVE`]).
#[inline(always)]
pub(super) fn live() -> (u32, u32) {
    LIVE.with(Cell::get)
}

/// True when a non-constant `Var` of recording id `rec` may be used now.
#[inline(always)]
pub(super) fn valid(rec: u32, (current, frozen): (u32, u32)) -> bool {
    // Both compares, no short circuit: whether a `Var` is the path's or the
    // frozen scene's varies from one operation to the next, so a branch
    // between the two would be mispredicted often.
    rec == current || rec == frozen
}

/// Panics unless `rec` (of a non-constant `Var`) belongs to the recording live
/// on this thread.
#[inline(always)]
pub(super) fn check_live(rec: u32) {
    let live = live();
    if !valid(rec, live) {
        stale(rec, live.0);
    }
}

/// Thread-exit guard: empties the leaked tape's buffers.
struct TapeRelease;

impl Drop for TapeRelease {
    fn drop(&mut self) {
        if let Ok(Some(t)) = TAPE.try_with(Cell::get) {
            if let Ok(mut t) = t.try_borrow_mut() {
                if LIVE
                    .try_with(Cell::get)
                    .is_ok_and(|(current, _)| current == 0)
                {
                    t.nodes = Vec::new();
                    t.inputs = Vec::new();
                    t.adj = Vec::new();
                }
            }
        }
    }
}

/// This thread's tape (created on first use).
#[inline(always)]
pub(super) fn tape() -> &'static RefCell<Tape> {
    match TAPE.with(Cell::get) {
        Some(t) => t,
        None => new_tape(),
    }
}

#[cold]
#[inline(never)]
fn new_tape() -> &'static RefCell<Tape> {
    let t: &'static RefCell<Tape> = Box::leak(Box::new(RefCell::new(Tape {
        nodes: Vec::new(),
        inputs: Vec::new(),
        adj: Vec::new(),
        frozen: (0, 0),
    })));
    TAPE.with(|c| c.set(Some(t)));
    // Touch the guard so its destructor is registered for this thread.
    let _ = RELEASE.try_with(|_| ());
    t
}

/// Run `f` on this thread's tape.
#[inline(always)]
pub(super) fn with_tape<R>(f: impl FnOnce(&RefCell<Tape>) -> R) -> R {
    f(tape())
}

/// Source of recording ids, unique across threads (0 is reserved for "none").
/// Threads take blocks of [`ID_BLOCK`] ids, so starting a recording touches the
/// shared counter only once per 4096 recordings (no cache-line ping-pong
/// between rayon workers starting a recording per path).
static NEXT_REC: AtomicU32 = AtomicU32::new(1);
const ID_BLOCK: u32 = 1 << 12;

thread_local! {
    /// This thread's current block of ids: `(next, end)`.
    static IDS: Cell<(u32, u32)> = const { Cell::new((0, 0)) };
}

pub(super) fn fresh_id() -> u32 {
    IDS.with(|c| {
        let (mut next, mut end) = c.get();
        loop {
            if next == end {
                next = NEXT_REC.fetch_add(ID_BLOCK, AtomicOrdering::Relaxed);
                end = next.wrapping_add(ID_BLOCK);
            }
            let id = next;
            next = next.wrapping_add(1);
            if id != 0 {
                c.set((next, end));
                return id;
            }
        }
    })
}

#[cold]
#[inline(never)]
pub(super) fn stale(var_rec: u32, tape_rec: u32) -> ! {
    if tape_rec == 0 {
        panic!(
            "usray_ad::reverse: a Var was used after its Recording ended (no recording is \
             live on this thread); Vars are only valid inside the Recording that made them"
        );
    }
    panic!(
        "usray_ad::reverse: a Var from recording #{var_rec} was used in recording \
         #{tape_rec}: it outlived its Recording or belongs to another thread's tape"
    );
}

impl Tape {
    #[inline(always)]
    pub(super) fn push(&mut self, node: Node) -> u32 {
        let i = self.nodes.len();
        debug_assert!(i < u32::MAX as usize, "reverse tape overflow");
        self.nodes.push(node);
        i as u32
    }

    /// Reset for a new recording `id`, keeping capacity.
    pub(super) fn begin(&mut self, id: u32) {
        LIVE.with(|c| c.set((id, 0)));
        self.nodes.clear();
        self.inputs.clear();
        self.frozen = (0, 0);
        self.nodes.push(DUMMY);
    }
}

/// Capacity (in nodes) of this thread's tape: stays constant once a per-path
/// loop has reached its longest path, which is how the tests check that the
/// steady state does not allocate.
///
/// ```
/// use usray_ad::reverse;
/// let _ = reverse::tape_capacity();
/// ```
pub fn tape_capacity() -> usize {
    with_tape(|t| {
        let t = t.borrow();
        t.nodes.capacity() + t.adj.capacity() + t.inputs.capacity()
    })
}
