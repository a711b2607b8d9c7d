//! A team of threads that spin between the short parallel loops of one implicit step.
//!
//! The implicit solver runs hundreds of parallel loops a step, each a few tens of microseconds
//! long at 16³, separated by serial work (the coarse levels of the multigrid, the scalars of the
//! conjugate gradients). Through rayon each loop woke a sleeping worker, and on a 2-vCPU virtual
//! machine that wake-up cost more than the loop: stepped from outside rayon's pool (as `jello
//! run` and Python step), the 16³ benchmark ran *slower* on two threads than on one (22.6–25.7
//! against 29.4–35.7 steps/s, a Zen 3 EPYC under KVM, 2026-11-27). OpenMP runtimes avoid it by
//! letting their threads spin between loops; so does this team, for the length of one step
//! only (the same job on two threads, medians of 8 alternated runs: 29.4 steps/s through
//! rayon, 46.1 on the team; 34.6 on one thread).
//!
//! [`run`] starts the team on rayon's threads (as many as the current pool has, `jello bench
//! --threads` and `RAYON_NUM_THREADS` set it, up to the cores the process may use) and
//! [`for_each`] spreads a loop's items over it.
//! Items are claimed one by one. A loop of up to [`OWNED_ITEMS`] items is cut into one
//! contiguous block per thread, and each thread first claims the items of its own block: a loop
//! repeated over the same data (the passes of an explicit step, the sweeps of a solve) keeps
//! each block on the same thread, in its core's caches, for as long as the team lasts. A thread
//! done with its block then takes the others' unclaimed items, from the far end, so a slow or
//! missing thread holds nothing up. Which thread computes an item still varies, but each item is
//! computed the same way whoever takes it: callers split their work into items that do not
//! depend on the thread count, and results are bit for bit the same for any number of threads.
//! Outside [`run`], on a thread that is not the team's leader, and without the `parallel`
//! feature (wasm), [`for_each`] runs the items in order on the calling thread.
//!
//! Waiting threads spin (with the processor's spin hint) for some tens of microseconds, then
//! yield their core at each turn, and never sleep: a step keeps the team's threads busy while
//! it lasts, and gives them back when it ends; where other work needs the cores, the yields let
//! it run. A helper that never starts (the pool busy with other work) costs nothing: the leader
//! claims every item itself.

use crate::vec3::Vec3;

/// Loops of at most this many items are cut into a block per thread (see the module's
/// documentation); the items of longer ones are claimed in order by whichever thread is free.
pub const OWNED_ITEMS: usize = 64;

#[cfg(feature = "parallel")]
mod spinning {
    use super::OWNED_ITEMS;
    use std::cell::Cell;
    use std::sync::atomic::{AtomicBool, AtomicPtr, AtomicU64, AtomicUsize, Ordering};

    /// One parallel loop, on the leader's stack while it lasts.
    struct Job<'a> {
        body: &'a (dyn Fn(usize) + Sync),
    }

    /// What the leader and its helpers share.
    pub(super) struct Team {
        /// The current loop of more than [`OWNED_ITEMS`] items: its number, its item count and
        /// its next unclaimed item (see [`NUMBER`], [`ITEMS`]), in one word so that a claim is
        /// of one loop's item.
        claim: AtomicU64,
        /// The current loop of at most [`OWNED_ITEMS`] items: bit `i` set once item `i` is
        /// claimed, and the bits past its items set. Every bit is set between such loops, so a
        /// claimed bit is always an item of the loop in progress.
        owned: AtomicU64,
        /// The item count of the current loop of at most [`OWNED_ITEMS`] items (where the
        /// threads' blocks are).
        owned_items: AtomicUsize,
        /// The current loop (valid while it has unfinished items).
        job: AtomicPtr<Job<'static>>,
        /// Items of the current loop finished.
        done: AtomicUsize,
        /// A helper's item panicked: the leader panics too, once the loop is over.
        panicked: AtomicBool,
        /// The step is over: helpers return.
        finished: AtomicBool,
        /// Helpers started.
        started: AtomicUsize,
        /// Threads in the team, the leader included.
        size: usize,
    }

    thread_local! {
        /// The team this thread leads, while it does.
        static LEADING: Cell<*const Team> = const { Cell::new(std::ptr::null()) };
        /// Whether this thread leads a team or helps one (further down its stack, maybe).
        static IN_TEAM: Cell<bool> = const { Cell::new(false) };
    }

    /// Sets `IN_TEAM` while it lives, then puts back what it was.
    struct InTeam(bool);

    impl InTeam {
        fn enter() -> InTeam {
            InTeam(IN_TEAM.replace(true))
        }
    }

    impl Drop for InTeam {
        fn drop(&mut self) {
            IN_TEAM.set(self.0);
        }
    }

    /// `claim`'s low 20 bits hold the next unclaimed item, the next 20 the item count, and the
    /// bits from `NUMBER` the loop's number.
    const ITEMS: u32 = 20;
    const NUMBER: u32 = 40;
    const MASK: u64 = (1 << ITEMS) - 1;

    /// The bits of `owned` of the items `0..items` (at most [`OWNED_ITEMS`]).
    fn item_bits(items: usize) -> u64 {
        if items >= OWNED_ITEMS {
            u64::MAX
        } else {
            (1 << items) - 1
        }
    }

    /// The items member `member` of a team of `size` claims first in a loop of `items` items:
    /// contiguous blocks in member order, the first (the leader's) never empty.
    pub(super) fn own_block(member: usize, items: usize, size: usize) -> std::ops::Range<usize> {
        (member * items).div_ceil(size)..((member + 1) * items).div_ceil(size)
    }

    /// Idle turns of a helper per look for rayon's pending work.
    const RAYON_EVERY: u32 = 32;

    /// Turns a waiting thread spins (tens of microseconds: longer than most of the serial work
    /// between a step's loops) before it also yields its core at each turn. With more threads
    /// than cores (other programs, other tests, a pool larger than the machine) a spinning
    /// thread would hold the core that the thread it waits for needs.
    const SPIN_TURNS: u32 = 1024;

    /// Waits one turn: the processor's spin hint, or after `SPIN_TURNS` turns a yield of the
    /// core to the operating system.
    fn pause(turns: u32) {
        if turns < SPIN_TURNS {
            std::hint::spin_loop();
        } else {
            std::thread::yield_now();
        }
    }

    impl Team {
        fn new(size: usize) -> Team {
            Team {
                size,
                claim: AtomicU64::new(0),
                owned: AtomicU64::new(u64::MAX),
                owned_items: AtomicUsize::new(0),
                job: AtomicPtr::new(std::ptr::null_mut()),
                done: AtomicUsize::new(0),
                panicked: AtomicBool::new(false),
                finished: AtomicBool::new(false),
                started: AtomicUsize::new(0),
            }
        }

        /// Claims the next item of the loop `claim` was read in; `None` when it has none left
        /// or a later loop has begun.
        fn take(&self, mut claim: u64) -> Option<usize> {
            loop {
                let index = claim & MASK;
                if index >= (claim >> ITEMS) & MASK {
                    return None;
                }
                match self.claim.compare_exchange_weak(
                    claim,
                    claim + 1,
                    Ordering::AcqRel,
                    Ordering::Acquire,
                ) {
                    Ok(_) => return Some(index as usize),
                    Err(now) if now >> NUMBER == claim >> NUMBER => claim = now,
                    Err(_) => return None,
                }
            }
        }

        /// Claims an item of the current loop of at most [`OWNED_ITEMS`] items, for team
        /// member `member` (the leader is 0): the first unclaimed one of its own block, else
        /// the last unclaimed one of the loop; `None` when none is left.
        fn take_owned(&self, member: usize) -> Option<usize> {
            let mut owned = self.owned.load(Ordering::Acquire);
            if owned == u64::MAX {
                return None;
            }
            // Read after `owned`, so maybe of a later loop: then the block is only a poor
            // guess, and any bit claimed below is still an item of the loop in progress.
            let items = self.owned_items.load(Ordering::Relaxed).min(OWNED_ITEMS);
            let mut own = own_block(member, items, self.size);
            loop {
                let index = match own.next() {
                    Some(i) if owned & 1 << i == 0 => i,
                    Some(_) => continue,
                    None if owned == u64::MAX => return None,
                    None => 63 - (!owned).leading_zeros() as usize,
                };
                // Acquire: the leader's release of this loop's bits (continued by every claim)
                // makes its `job` visible.
                let before = self.owned.fetch_or(1 << index, Ordering::AcqRel);
                if before & 1 << index == 0 {
                    return Some(index);
                }
                owned = before | 1 << index;
            }
        }

        /// The leader's side of one loop.
        fn lead(&self, items: usize, body: &(dyn Fn(usize) + Sync)) {
            assert!(items as u64 <= MASK, "{items} items in one parallel loop");
            let job = Job { body };
            self.done.store(0, Ordering::Relaxed);
            // SAFETY (of the helpers' reads): the pointer is read only by a helper that claimed
            // an item of this loop, and the leader does not return (ending `job`'s life) before
            // every claimed item is done.
            let job_ptr: *const Job = &job;
            self.job
                .store(job_ptr as *mut Job<'static>, Ordering::Relaxed);
            let owned = items <= OWNED_ITEMS;
            if owned {
                self.owned_items.store(items, Ordering::Relaxed);
                self.owned.store(!item_bits(items), Ordering::Release);
            } else {
                let number = (self.claim.load(Ordering::Relaxed) >> NUMBER) + 1;
                let claim = number << NUMBER | (items as u64) << ITEMS;
                self.claim.store(claim, Ordering::Release);
            }
            let next = || match owned {
                true => self.take_owned(0),
                false => self.take(self.claim.load(Ordering::Acquire)),
            };
            // A panic of the leader's own item waits, like the rest, until the helpers' items
            // are done: they borrow from this frame. The items left are then claimed, not run.
            let mut panic = None;
            while let Some(index) = next() {
                if panic.is_none() {
                    let ran =
                        std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| body(index)));
                    panic = ran.err();
                }
                self.done.fetch_add(1, Ordering::Release);
            }
            let mut turns = 0u32;
            while self.done.load(Ordering::Acquire) < items {
                pause(turns);
                turns = turns.saturating_add(1);
            }
            if let Some(panic) = panic {
                std::panic::resume_unwind(panic);
            }
            if self.panicked.load(Ordering::Relaxed) {
                panic!("an item of a parallel loop panicked on a helper thread");
            }
        }

        /// A helper: claims items of each loop until the step is over. Between loops, once
        /// every helper has started, it also runs rayon's pending work (the halves of the
        /// leader's `rayon::join`s, which it would otherwise never steal).
        ///
        /// A thread already in a team (its leader waiting in a `rayon::join`, or a helper
        /// running rayon's work) does not help: the work further down its stack may be what a
        /// leader waits for, and this loop ends only when that leader's step does. It returns
        /// at once, and the team has one helper fewer.
        fn help(&self, helpers: usize) {
            // The leader is member 0.
            let member = self.started.fetch_add(1, Ordering::AcqRel) + 1;
            if IN_TEAM.get() {
                return;
            }
            let _in_team = InTeam::enter();
            let mut idle = 0u32;
            while !self.finished.load(Ordering::Acquire) {
                let claimed = self
                    .take(self.claim.load(Ordering::Acquire))
                    .or_else(|| self.take_owned(member));
                let Some(index) = claimed else {
                    // Looking for rayon's work takes longer than a look at `claim`: once every
                    // `RAYON_EVERY` idle turns. Before every helper has started, the next one's
                    // start may be this thread's own pending work: running it here would nest a
                    // helper in this one.
                    idle = idle.saturating_add(1);
                    if idle % RAYON_EVERY != 0
                        || self.started.load(Ordering::Acquire) < helpers
                        || rayon::yield_now() != Some(rayon::Yield::Executed)
                    {
                        pause(idle);
                    }
                    continue;
                };
                idle = 0;
                // SAFETY: this item of the loop is claimed and not yet done, so the leader is
                // still in `lead` for that loop and `job` points at its live `Job`.
                let job = unsafe { &*self.job.load(Ordering::Acquire) };
                let ran =
                    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| (job.body)(index)));
                if ran.is_err() {
                    self.panicked.store(true, Ordering::Relaxed);
                }
                self.done.fetch_add(1, Ordering::Release);
            }
        }
    }

    /// Starts `left` of the `helpers` helpers of `team`, one on each thread that steals one.
    fn start_helpers(team: &Team, helpers: usize, left: usize) {
        match left {
            0 => {}
            1 => team.help(helpers),
            _ => {
                rayon::join(
                    || team.help(helpers),
                    || start_helpers(team, helpers, left - 1),
                );
            }
        }
    }

    /// Threads of a team in the current pool: one per thread of the pool, but no more than the
    /// cores this process may use (a spinning team larger than the machine only waits for its
    /// own members to be scheduled).
    fn team_size() -> usize {
        rayon::current_num_threads().min(cores()).max(1)
    }

    /// The cores this process may use, asked once: the question reads files (cgroup quotas)
    /// and allocates.
    pub(super) fn cores() -> usize {
        static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
        *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
    }

    pub(super) fn run<R: Send>(f: impl FnOnce() -> R + Send) -> R {
        let size = team_size();
        if size == 1 || !LEADING.get().is_null() {
            return f();
        }
        let helpers = size - 1;
        let team = Team::new(size);
        let (result, ()) = rayon::join(
            || {
                // Marks the team led on this thread, and ends the step however `f` ends.
                struct Leading<'a>(&'a Team);
                impl Drop for Leading<'_> {
                    fn drop(&mut self) {
                        LEADING.set(std::ptr::null());
                        self.0.finished.store(true, Ordering::Release);
                    }
                }
                LEADING.set(&team);
                let _leading = Leading(&team);
                let _in_team = InTeam::enter();
                f()
            },
            || start_helpers(&team, helpers, helpers),
        );
        result
    }

    pub(super) fn for_each(items: usize, body: &(dyn Fn(usize) + Sync)) {
        let team = LEADING.get();
        if team.is_null() || items < 2 {
            (0..items).for_each(body);
            return;
        }
        // SAFETY: `LEADING` is set only inside `run`, while its `team` lives.
        unsafe { &*team }.lead(items, body);
    }

    pub(super) fn serially<R>(f: impl FnOnce() -> R) -> R {
        /// Gives the team back to the thread however `f` ends.
        struct Restore(*const Team);
        impl Drop for Restore {
            fn drop(&mut self) {
                LEADING.set(self.0);
            }
        }
        let _restore = Restore(LEADING.replace(std::ptr::null()));
        f()
    }

    pub(super) fn threads() -> usize {
        let team = LEADING.get();
        if team.is_null() {
            1
        } else {
            // SAFETY: as in `for_each`.
            unsafe { &*team }.size
        }
    }
}

/// Runs `f` with a team of the current rayon pool's threads: within it, [`for_each`] on this
/// thread spreads its items over them. Without the `parallel` feature, just `f()`.
pub fn run<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    #[cfg(feature = "parallel")]
    return spinning::run(f);
    #[cfg(not(feature = "parallel"))]
    f()
}

/// `f()` with the team this thread leads set aside: its loops run in order on this thread (and
/// [`threads`] is 1), for work too small to be worth the others' start at each loop. The team's
/// other threads wait meanwhile, as they wait for the leader's serial work.
pub fn serially<R>(f: impl FnOnce() -> R) -> R {
    #[cfg(feature = "parallel")]
    return spinning::serially(f);
    #[cfg(not(feature = "parallel"))]
    f()
}

/// `(a(), b())`, the two at once where this thread leads a team of two or more: `b` on a
/// helper while `a` runs here (each with its own loops in order on its thread, see
/// [`serially`]); in order on this thread otherwise. For independent serial work, such as the
/// parts of a solver's setup.
pub fn join<A: Send, B: Send>(
    a: impl FnOnce() -> A + Send,
    b: impl FnOnce() -> B + Send,
) -> (A, B) {
    if threads() < 2 {
        return (a(), b());
    }
    use std::sync::Mutex;
    fn take<T>(m: &Mutex<Option<T>>) -> Option<T> {
        m.lock().unwrap_or_else(|e| e.into_inner()).take()
    }
    fn put<T>(m: &Mutex<Option<T>>, v: T) {
        *m.lock().unwrap_or_else(|e| e.into_inner()) = Some(v);
    }
    let tasks = (Mutex::new(Some(a)), Mutex::new(Some(b)));
    let results = (Mutex::new(None), Mutex::new(None));
    // Two items: the leader's own block is the first, a helper's the second (see the module
    // documentation), and a thread done with its own takes the other if it is still waiting.
    for_each(2, &|i| {
        if i == 0 {
            put(
                &results.0,
                serially(take(&tasks.0).expect("each item runs once")),
            );
        } else {
            put(
                &results.1,
                serially(take(&tasks.1).expect("each item runs once")),
            );
        }
    });
    let done = "both items ran (a panic in either is raised by the loop)";
    (take(&results.0).expect(done), take(&results.1).expect(done))
}

/// `body(i)` for every `i` in `0..items`, spread over the team this thread leads (in order on
/// this thread when it leads none). `body` must give the same results whichever thread runs an
/// item and in whatever order the items run.
pub fn for_each(items: usize, body: &(dyn Fn(usize) + Sync)) {
    #[cfg(feature = "parallel")]
    spinning::for_each(items, body);
    #[cfg(not(feature = "parallel"))]
    (0..items).for_each(body);
}

/// `f` of each chunk of `size` items of `0..n` (larger where that makes more than
/// [`OWNED_ITEMS`] chunks), spread as [`for_each`] spreads them, and how many chunks there are:
/// for the maxima, sums and tests over all points that a step takes between its parallel loops,
/// which on the leader alone keep the other threads waiting.
pub fn map_chunks<R: Copy + Default + Send>(
    n: usize,
    size: usize,
    f: &(dyn Fn(std::ops::Range<usize>) -> R + Sync),
) -> ([R; OWNED_ITEMS], usize) {
    let size = size.max(n.div_ceil(OWNED_ITEMS)).max(1);
    let chunks = n.div_ceil(size);
    let mut parts = [R::default(); OWNED_ITEMS];
    for_each_mut(&mut parts[..chunks], &|c, part| {
        *part = f(c * size..((c + 1) * size).min(n));
    });
    (parts, chunks)
}

/// The smallest box holding `points` (its lowest and highest corners; inside out, from +∞ to
/// −∞, for none), in chunks of `size` points spread as [`map_chunks`] spreads them.
pub fn bounds(points: &[Vec3], size: usize) -> (Vec3, Vec3) {
    let far = Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let grow = |(lo, hi): (Vec3, Vec3), (l, h): (Vec3, Vec3)| (lo.min(l), hi.max(h));
    let (boxes, chunks) = map_chunks(points.len(), size, &|at| {
        (points[at].iter()).fold((far, -far), |b, &p| grow(b, (p, p)))
    });
    boxes[..chunks].iter().fold((far, -far), |b, &c| grow(b, c))
}

/// `body(i, &mut items[i])` for every item, spread as [`for_each`] spreads them.
pub fn for_each_mut<S: Send>(items: &mut [S], body: &(dyn Fn(usize, &mut S) + Sync)) {
    let base = Base(items.as_mut_ptr());
    for_each(items.len(), &|i| {
        // SAFETY: `for_each` runs each index once, so each item is borrowed once, and `items`
        // is borrowed mutably for the whole loop.
        body(i, unsafe { &mut *base.at(i) })
    });
}

/// What [`for_each_mut_with_runs`] calls for each item: its index, the item and its runs.
pub type RunBody<'a, S, T, const K: usize> = dyn Fn(usize, &mut S, [&mut [T]; K]) + Sync + 'a;

/// `body(i, &mut items[i], parts)` for each item `i`, `parts` the elements `range(i)` of each
/// of `slices` (all of one length): runs of elements that follow one another in the items'
/// order without overlapping (checked), such as the points of each body; spread as
/// [`for_each`] spreads them.
pub fn for_each_mut_with_runs<S: Send, T: Send, const K: usize>(
    items: &mut [S],
    slices: [&mut [T]; K],
    range: &(dyn Fn(usize) -> std::ops::Range<usize> + Sync),
    body: &RunBody<'_, S, T, K>,
) {
    let len = slices.first().map_or(0, |s| s.len());
    assert!(slices.iter().all(|s| s.len() == len));
    let mut end = 0;
    for i in 0..items.len() {
        let run = range(i);
        assert!(end <= run.start && run.start <= run.end && run.end <= len);
        end = run.end;
    }
    let item = Base(items.as_mut_ptr());
    let bases = slices.map(|s| Base(s.as_mut_ptr()));
    for_each(items.len(), &|i| {
        let run = range(i);
        // SAFETY: `for_each` runs each index once, so each item is borrowed once; the runs of
        // distinct indices do not overlap (checked above) and lie within the slices, so each
        // element is borrowed once; everything is borrowed mutably for the whole loop.
        body(i, unsafe { &mut *item.at(i) }, {
            bases.map(|b| unsafe { std::slice::from_raw_parts_mut(b.at(run.start), run.len()) })
        })
    });
}

/// `body(i, parts)` for each chunk `i` of `size` elements of `slices` (all of one length; the
/// last chunk may be short), `parts` the chunk of each slice; spread as [`for_each`] spreads
/// them.
pub fn for_each_chunk<T: Send, const K: usize>(
    slices: [&mut [T]; K],
    size: usize,
    body: &(dyn Fn(usize, [&mut [T]; K]) + Sync),
) {
    let len = slices.first().map_or(0, |s| s.len());
    assert!(slices.iter().all(|s| s.len() == len) && size > 0);
    let bases = slices.map(|s| Base(s.as_mut_ptr()));
    for_each(len.div_ceil(size), &|i| {
        let (start, end) = (i * size, ((i + 1) * size).min(len));
        // SAFETY: `for_each` runs each index once and the chunks of distinct indices do not
        // overlap, so each element is borrowed once; the slices are borrowed mutably for the
        // whole loop.
        body(
            i,
            bases.map(|b| unsafe { std::slice::from_raw_parts_mut(b.at(start), end - start) }),
        )
    });
}

/// Chunk `i` of each of two sets of slices, as [`for_each_chunk_pair`] hands them over.
pub type ChunkPair<'a, T, U, const K: usize, const L: usize> = ([&'a mut [T]; K], [&'a mut [U]; L]);

/// [`for_each_chunk`] over two sets of slices of different types (all of one length), chunk
/// `i` of each handed to `body` together.
pub fn for_each_chunk_pair<T: Send, U: Send, const K: usize, const L: usize>(
    (first, second): ChunkPair<'_, T, U, K, L>,
    size: usize,
    body: &(dyn Fn(usize, ChunkPair<'_, T, U, K, L>) + Sync),
) {
    let len = first.first().map_or(0, |s| s.len());
    assert!(first.iter().all(|s| s.len() == len) && second.iter().all(|s| s.len() == len));
    assert!(size > 0);
    let (a, b) = (
        first.map(|s| Base(s.as_mut_ptr())),
        second.map(|s| Base(s.as_mut_ptr())),
    );
    for_each(len.div_ceil(size), &|i| {
        let (start, end) = (i * size, ((i + 1) * size).min(len));
        // SAFETY: as in `for_each_chunk`: each chunk runs once, and chunks do not overlap.
        let parts = unsafe {
            (
                a.map(|p| std::slice::from_raw_parts_mut(p.at(start), end - start)),
                b.map(|p| std::slice::from_raw_parts_mut(p.at(start), end - start)),
            )
        };
        body(i, parts)
    });
}

/// [`for_each_chunk`], with what `body` returns for chunk `i` stored in `out[i]` (`out` has one
/// element per chunk): a reduction's partial results, for the caller to combine in order.
pub fn for_each_chunk_into<T: Send, R: Send, const K: usize>(
    slices: [&mut [T]; K],
    size: usize,
    out: &mut [R],
    body: &(dyn Fn(usize, [&mut [T]; K]) -> R + Sync),
) {
    let len = slices.first().map_or(0, |s| s.len());
    assert!(size > 0 && out.len() == len.div_ceil(size));
    let out = Base(out.as_mut_ptr());
    for_each_chunk(slices, size, &|i, parts| {
        let result = body(i, parts);
        // SAFETY: chunk `i` runs once and `out` has an element per chunk, borrowed mutably for
        // the whole loop.
        unsafe { *out.at(i) = result };
    });
}

/// The least items of a thread's run in [`bucket_sort`] (fewer items in all run on fewer
/// threads): a run costs a row of counts as long as the buckets.
const SORTED_PER_RANGE: usize = 2048;

/// Items that [`bucket_sort`] sorts: each with its entries, each entry in a bucket.
pub trait Bucketed: Sync {
    type Entry: Copy + Default + Send + Sync;

    /// Calls `emit(bucket, entry)` for each entry of item `i`, the same ones in the same order
    /// at each call.
    fn entries(&self, i: usize, emit: impl FnMut(usize, Self::Entry));
}

/// A counting sort on the team of `sorted`'s items `0..items`' entries into `out`, so that
/// `out[starts[b]..starts[b + 1]]` are bucket `b`'s entries (buckets below `starts.len() − 1`)
/// in the items' order, whatever the thread count. The items are cut into one run per thread;
/// each counts its entries per bucket into its own row of `counts` (a buffer, grown as needed),
/// the rows' prefix sum gives each run its slots in each bucket after the runs before it, and
/// each run writes its entries there.
pub fn bucket_sort<B: Bucketed>(
    items: usize,
    sorted: &B,
    starts: &mut [u32],
    counts: &mut Vec<u32>,
    out: &mut Vec<B::Entry>,
) {
    let buckets = starts.len() - 1;
    let runs = threads().min(items.div_ceil(SORTED_PER_RANGE)).max(1);
    let run = |r: usize| r * items / runs..(r + 1) * items / runs;
    if counts.len() < runs * buckets {
        counts.resize(runs * buckets, 0);
    }
    let counts = &mut counts[..runs * buckets];
    for_each_chunk([&mut counts[..]], buckets, &|r, [row]| {
        row.fill(0);
        for i in run(r) {
            sorted.entries(i, |b, _| row[b] += 1);
        }
    });
    // Each run's slot in each bucket: after the bucket's entries of the runs before it.
    let mut sum = 0u32;
    for b in 0..buckets {
        starts[b] = sum;
        for r in 0..runs {
            let count = counts[r * buckets + b];
            counts[r * buckets + b] = sum;
            sum += count;
        }
    }
    starts[buckets] = sum;
    out.resize(sum as usize, B::Entry::default());
    let slots = Base(out.as_mut_ptr());
    for_each_chunk([&mut counts[..]], buckets, &|r, [next]| {
        for i in run(r) {
            sorted.entries(i, |b, entry| {
                let slot = next[b] as usize;
                next[b] += 1;
                // SAFETY: the runs' slots in each bucket are disjoint ranges of `out` (the
                // prefix sum above, of the counts of the same entries), each written once;
                // `out` is borrowed mutably for the whole loop.
                unsafe { *slots.at(slot) = entry };
            });
        }
    });
}

/// A pointer to the elements of a slice that a loop's items borrow apart.
struct Base<T>(*mut T);

impl<T> Clone for Base<T> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<T> Copy for Base<T> {}

// SAFETY: the elements are `Send`, and the loops above hand each to one thread at a time.
unsafe impl<T: Send> Sync for Base<T> {}

impl<T> Base<T> {
    /// # Safety
    /// `i` within the slice.
    unsafe fn at(self, i: usize) -> *mut T {
        unsafe { self.0.add(i) }
    }
}

/// Elements per chunk of a loop over `n` elements whose results do not depend on its chunks:
/// one chunk per thread of the team, none under `min` (smaller ones cost more to hand out
/// than they save).
pub fn chunk_size(n: usize, min: usize) -> usize {
    n.div_ceil(threads()).max(min).max(1)
}

/// Threads of the team this thread leads (1 when it leads none).
pub fn threads() -> usize {
    #[cfg(feature = "parallel")]
    return spinning::threads();
    #[cfg(not(feature = "parallel"))]
    1
}

#[cfg(all(test, feature = "parallel"))]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    }

    /// Within `serially` the team is set aside (one thread; the items in order on the leader),
    /// and back after it, also when `f` panics.
    #[test]
    fn serially_sets_the_team_aside_until_it_returns() {
        pool(2).install(|| {
            run(|| {
                // Two where the machine has two cores or more.
                let size = threads();
                let leader = std::thread::current().id();
                let order = std::sync::Mutex::new(Vec::new());
                serially(|| {
                    assert_eq!(threads(), 1);
                    for_each(8, &|i| {
                        assert_eq!(std::thread::current().id(), leader);
                        order.lock().unwrap().push(i);
                    });
                });
                assert_eq!(*order.lock().unwrap(), (0..8).collect::<Vec<_>>());
                assert_eq!(threads(), size);
                let panicked = std::panic::catch_unwind(|| serially(|| panic!("in serially")));
                assert!(panicked.is_err());
                assert_eq!(threads(), size);
            })
        });
    }

    /// `bounds` is the smallest box holding the points, whatever the chunks, and inside out for
    /// none.
    #[test]
    fn bounds_hold_the_points_in_the_smallest_box() {
        let points: Vec<Vec3> = (0..100)
            .map(|i| Vec3::new((i % 7) as f64, -(i as f64), ((i * 37) % 11) as f64 - 5.0))
            .collect();
        for size in [1, 3, 64, 1000] {
            let got = pool(2).install(|| run(|| bounds(&points, size)));
            assert_eq!(
                got,
                (Vec3::new(0.0, -99.0, -5.0), Vec3::new(6.0, 0.0, 5.0)),
                "{size}"
            );
        }
        let far = Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
        assert_eq!(bounds(&[], 4), (far, -far));
    }

    /// The chunks of `map_chunks` cover the items once, in order, each its `size` but the last,
    /// and no more than `OWNED_ITEMS` of them however small `size` is.
    #[test]
    fn map_chunks_cover_the_items_in_order() {
        // Items, the size asked, the chunks' size.
        for (n, size, want) in [(10, 3, 3), (9, 3, 3), (0, 3, 3), (1000, 1, 16), (5, 0, 1)] {
            let (ranges, chunks) =
                pool(2).install(|| run(|| map_chunks(n, size, &|at| (at.start, at.end))));
            let ranges = &ranges[..chunks];
            assert_eq!(chunks, n.div_ceil(want), "n {n}, size {size}: {ranges:?}");
            let mut next = 0;
            for &(start, end) in ranges {
                assert_eq!(start, next, "n {n}, size {size}: {ranges:?}");
                assert!(
                    end - start == want || end == n,
                    "n {n}, size {size}: {ranges:?}"
                );
                next = end;
            }
            assert_eq!(next, n, "n {n}, size {size}: {ranges:?}");
        }
    }

    /// Each item gets its own run of the slices, whatever thread takes it; elements between
    /// runs are left alone.
    #[test]
    fn runs_go_each_to_their_item() {
        let runs = [0..2, 2..5, 5..5, 7..10];
        let mut items = vec![0usize; runs.len()];
        let (mut a, mut b) = (vec![-1i64; 10], vec![-1i64; 10]);
        pool(2).install(|| {
            run(|| {
                for_each_mut_with_runs(
                    &mut items,
                    [&mut a[..], &mut b[..]],
                    &|i| runs[i].clone(),
                    &|i, item, [a, b]| {
                        *item = a.len();
                        a.fill(i as i64);
                        b.fill(10 * i as i64);
                    },
                )
            })
        });
        assert_eq!(items, [2, 3, 0, 3]);
        assert_eq!(a, [0, 0, 1, 1, 1, -1, -1, 3, 3, 3]);
        assert_eq!(b, [0, 0, 10, 10, 10, -1, -1, 30, 30, 30]);
    }

    /// A counting sort by bucket gives each bucket its entries in the items' order, on any
    /// number of threads, as a serial one does.
    #[test]
    fn bucket_sort_keeps_the_items_order_in_each_bucket() {
        // Item i has entries in buckets i² mod 7 .. (i mod 3) more, each entry (i, k).
        struct Squares;
        impl Bucketed for Squares {
            type Entry = (usize, usize);
            fn entries(&self, i: usize, mut emit: impl FnMut(usize, (usize, usize))) {
                for k in 0..=i % 3 {
                    emit((i * i + k) % 7, (i, k));
                }
            }
        }
        let items = 5 * SORTED_PER_RANGE + 3;
        let mut want = vec![Vec::new(); 7];
        for i in 0..items {
            Squares.entries(i, |b, e| want[b].push(e));
        }
        for threads in [1, 2, 3] {
            let (mut starts, mut counts, mut out) = (vec![0u32; 8], Vec::new(), Vec::new());
            pool(threads).install(|| {
                run(|| bucket_sort(items, &Squares, &mut starts, &mut counts, &mut out))
            });
            for (b, want) in want.iter().enumerate() {
                let got = &out[starts[b] as usize..starts[b + 1] as usize];
                assert_eq!(got, &want[..], "bucket {b}, {threads} threads");
            }
            assert_eq!(starts[7] as usize, want.iter().map(Vec::len).sum::<usize>());
        }
    }

    /// Each chunk of the two sets covers the same items, each once.
    #[test]
    fn chunk_pairs_cover_both_sets_alike() {
        let pool = pool(2);
        let (mut a, mut b) = (vec![0u32; 1000], vec![0.0f64; 1000]);
        pool.install(|| {
            run(|| {
                let parts = ([&mut a[..]], [&mut b[..]]);
                for_each_chunk_pair(parts, 64, &|c, ([a], [b])| {
                    assert_eq!(a.len(), b.len());
                    for (j, (a, b)) in a.iter_mut().zip(b).enumerate() {
                        *a += (c * 64 + j) as u32;
                        *b += 1.0;
                    }
                });
            })
        });
        assert!(a.iter().enumerate().all(|(i, &v)| v == i as u32));
        assert!(b.iter().all(|&v| v == 1.0));
    }

    /// Runs that overlap would lend an element twice: refused.
    #[test]
    #[should_panic]
    fn overlapping_runs_are_refused() {
        let runs = [0..3, 2..4];
        let mut a = [0.0; 4];
        for_each_mut_with_runs(
            &mut [(), ()],
            [&mut a[..]],
            &|i| runs[i].clone(),
            &|_, _, _| {},
        );
    }

    /// Every item of every loop runs exactly once, on any number of threads (more than this
    /// machine's cores included), from inside the pool and from outside it.
    #[test]
    fn every_item_runs_once() {
        let cores = super::spinning::cores();
        for threads in [1, 2, 3, 8] {
            let check = || {
                run(|| {
                    assert_eq!(super::threads(), threads.min(cores));
                    for items in [0, 1, 2, 5, 64, 1000] {
                        let counts: Vec<AtomicUsize> =
                            (0..items).map(|_| AtomicUsize::new(0)).collect();
                        for_each(items, &|i| {
                            counts[i].fetch_add(1, Ordering::Relaxed);
                        });
                        assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 1));
                    }
                    let mut values = vec![0usize; 1001];
                    for_each_chunk([&mut values[..]], 7, &|chunk, [part]| {
                        for (i, v) in part.iter_mut().enumerate() {
                            *v += chunk * 7 + i;
                        }
                    });
                    assert!(values.iter().enumerate().all(|(i, &v)| v == i));
                    let mut firsts = vec![0usize; 1001usize.div_ceil(7)];
                    for_each_chunk_into([&mut values[..]], 7, &mut firsts, &|chunk, [part]| {
                        part.iter_mut().for_each(|v| *v += 1);
                        chunk * 7 + part.len()
                    });
                    assert!(values.iter().enumerate().all(|(i, &v)| v == i + 1));
                    assert!(firsts
                        .iter()
                        .enumerate()
                        .all(|(c, &e)| e == (c * 7 + 7).min(1001)));
                    let mut items = vec![1usize; 33];
                    for_each_mut(&mut items, &|i, item| *item += i);
                    assert!(items.iter().enumerate().all(|(i, &v)| v == i + 1));
                })
            };
            pool(threads).install(check);
        }
        // Outside any team: in order on this thread.
        assert_eq!(super::threads(), 1);
        let order = std::sync::Mutex::new(Vec::new());
        for_each(4, &|i| order.lock().unwrap().push(i));
        assert_eq!(*order.lock().unwrap(), [0, 1, 2, 3]);
    }

    /// The items of a loop are spread over the threads: with as many items as the team has
    /// threads, each waiting until all have started, the loop can only end if every thread took
    /// one.
    #[test]
    fn the_helpers_take_items() {
        let pool = pool(3);
        pool.install(|| {
            run(|| {
                let team = super::threads();
                assert_eq!(team, super::spinning::cores().min(3));
                let started = AtomicUsize::new(0);
                let threads_seen = std::sync::Mutex::new(std::collections::HashSet::new());
                for_each(team, &|_| {
                    started.fetch_add(1, Ordering::AcqRel);
                    while started.load(Ordering::Acquire) < team {
                        std::hint::spin_loop();
                    }
                    threads_seen
                        .lock()
                        .unwrap()
                        .insert(std::thread::current().id());
                });
                assert_eq!(threads_seen.lock().unwrap().len(), team);
            })
        });
    }

    /// The threads' blocks of a loop cover its items once each, in order, the leader's first
    /// and never empty.
    #[test]
    fn the_blocks_cover_the_items() {
        for size in 1..=17 {
            for items in 0..=super::OWNED_ITEMS {
                let mut next = 0;
                for member in 0..size {
                    let block = super::spinning::own_block(member, items, size);
                    assert_eq!(block.start, next, "{member} of {size}, {items} items");
                    assert!(block.end >= block.start);
                    next = block.end;
                }
                assert_eq!(next, items);
                assert!(items == 0 || !super::spinning::own_block(0, items, size).is_empty());
            }
        }
    }

    /// A loop repeated over the same items keeps each item on the same thread while the team
    /// lasts: with one item per thread, each item waiting until every thread has one, no thread
    /// can take another's, so each takes its own block's (with claims in order of arrival, the
    /// helpers would take the items in whatever order they came to the loop).
    #[test]
    fn each_thread_keeps_its_items() {
        pool(8).install(|| {
            run(|| {
                let team = super::threads();
                let owners = std::sync::Mutex::new(vec![None; team]);
                for round in 0..20 {
                    let started = AtomicUsize::new(0);
                    for_each(team, &|i| {
                        started.fetch_add(1, Ordering::AcqRel);
                        while started.load(Ordering::Acquire) < team {
                            std::hint::spin_loop();
                        }
                        let me = std::thread::current().id();
                        let mut owners = owners.lock().unwrap();
                        let owner = owners[i].get_or_insert(me);
                        assert_eq!(*owner, me, "item {i} changed threads in round {round}");
                    });
                }
            })
        });
    }

    /// `join` returns both closures' results: in order outside a team, and on a team of two
    /// or more at once, on two threads (each closure below waits until the other has started,
    /// so run one after the other they would never finish: a limit turns that into a
    /// failure), each with its own loops in order on its thread.
    #[test]
    fn join_runs_both_closures_at_once_on_a_team() {
        assert_eq!(join(|| 1, || "two"), (1, "two"));
        pool(2).install(|| {
            run(|| {
                if super::threads() < 2 {
                    eprintln!("skipped: this machine gives the team one thread");
                    return;
                }
                let started = AtomicUsize::new(0);
                let both_started = || {
                    started.fetch_add(1, Ordering::AcqRel);
                    let waiting = std::time::Instant::now();
                    while started.load(Ordering::Acquire) < 2 {
                        assert!(
                            waiting.elapsed() < std::time::Duration::from_secs(20),
                            "join ran its closures one after the other"
                        );
                        std::hint::spin_loop();
                    }
                    std::thread::current().id()
                };
                let (a, b) = join(both_started, both_started);
                assert_ne!(a, b);
                let in_order = || {
                    let seen = std::sync::Mutex::new(Vec::new());
                    for_each(5, &|i| seen.lock().unwrap().push(i));
                    (seen.into_inner().unwrap(), super::threads())
                };
                assert_eq!(
                    join(in_order, in_order),
                    ((vec![0, 1, 2, 3, 4], 1), (vec![0, 1, 2, 3, 4], 1))
                );
            })
        });
    }

    /// A team inside a team's step runs on the outer one; rayon work from the leader still
    /// runs (on the helpers or on the leader).
    #[test]
    fn nested_runs_and_rayon_work_finish() {
        pool(2).install(|| {
            let sum = run(|| {
                let inner = run(|| {
                    let (a, b) = rayon::join(|| 1, || 2);
                    a + b
                });
                let total = AtomicUsize::new(0);
                for_each(10, &|i| {
                    total.fetch_add(i, Ordering::Relaxed);
                });
                inner + total.load(Ordering::Relaxed)
            });
            assert_eq!(sum, 48);
        });
    }

    /// Nested `rayon::join`s in a leader's step (as the force pass makes on large lattices),
    /// interleaved with loops, on 3 to 8 threads: every step ends. (Before helpers checked
    /// `IN_TEAM`, a leader that took a helper's start while waiting in a join helped its own
    /// team until its own step ended, that is forever: this test hung within a minute.)
    #[test]
    fn steps_with_nested_joins_end() {
        fn split(depth: u32) -> u64 {
            if depth == 0 {
                return 1;
            }
            let (a, b) = rayon::join(|| split(depth - 1), || split(depth - 1));
            a + b
        }
        for threads in [3, 4, 6, 8] {
            pool(threads).install(|| {
                for _ in 0..5000 {
                    let total = run(|| {
                        let mut total = 0;
                        for _ in 0..5 {
                            total += split(4);
                            let sum = AtomicUsize::new(0);
                            for_each(8, &|i| {
                                sum.fetch_add(i, Ordering::Relaxed);
                            });
                            total += sum.load(Ordering::Relaxed) as u64;
                        }
                        total
                    });
                    assert_eq!(total, 5 * (16 + 28));
                }
            });
        }
    }

    /// A panic in the leader's own item waits for the helpers' items, which borrow from the
    /// leader's frame, before it unwinds that frame.
    #[test]
    fn a_leaders_panic_waits_for_the_helpers_items() {
        use std::sync::atomic::AtomicBool;
        /// Marks the leader's frame unwound.
        struct Frame<'a>(&'a AtomicBool);
        impl Drop for Frame<'_> {
            fn drop(&mut self) {
                self.0.store(true, Ordering::Release);
            }
        }
        let pool = pool(2);
        let (started, unwound, too_early) = (
            AtomicUsize::new(0),
            AtomicBool::new(false),
            AtomicBool::new(false),
        );
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            pool.install(|| {
                run(|| {
                    let _frame = Frame(&unwound);
                    let leader = std::thread::current().id();
                    for_each(2, &|_| {
                        started.fetch_add(1, Ordering::AcqRel);
                        if std::thread::current().id() != leader {
                            std::thread::sleep(std::time::Duration::from_millis(100));
                            if unwound.load(Ordering::Acquire) {
                                too_early.store(true, Ordering::Release);
                            }
                            return;
                        }
                        // The leader's item: once the helper has its own (or after a second),
                        // it panics.
                        let since = std::time::Instant::now();
                        while started.load(Ordering::Acquire) < 2 && since.elapsed().as_secs() < 1 {
                            std::hint::spin_loop();
                        }
                        panic!("the leader's item");
                    });
                })
            })
        }));
        assert!(result.is_err());
        assert!(
            !too_early.load(Ordering::Acquire),
            "the leader's frame unwound while a helper's item ran"
        );
    }

    /// A panic in an item reaches the leader (whichever thread ran it), and the team ends.
    #[test]
    fn a_panicking_item_panics_the_leader() {
        let pool = pool(2);
        for item in [0, 1] {
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                pool.install(|| {
                    run(|| {
                        for_each(2, &|i| {
                            assert!(i != item, "item {i}");
                        });
                    })
                })
            }));
            assert!(result.is_err());
        }
        // The pool is still usable.
        let cores = super::spinning::cores();
        assert_eq!(pool.install(|| run(threads)), cores.min(2));
    }
}
