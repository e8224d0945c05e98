//! Where filter steps run: never on the async runtime's threads.
//!
//! Two ways, chosen per step by the caller: a step that has the machine to
//! itself runs on the shared pool, whose `threads` workers split its
//! particles between them (the latency of `omcl localize`); when several
//! steps are waiting, each runs whole on one of `threads` lanes (a thread
//! with a single-threaded rayon pool, so the filter's parallel loops run
//! sequentially inside it), taking tasks in arrival order. On the shared
//! pool a worker waiting inside one step's parallel loop would take whole
//! steps of other sessions and run them nested; lanes avoid that and the
//! splitting's overhead when there is enough work for every core anyway.
//!
//! The pool counts its tasks until each has finished and dropped what it
//! captured ([`Compute::running`]): a step's last reference to its session
//! or to the server's state may be the one that releases a map's Embree
//! scene, and the process must not exit while a pool thread does that
//! (Embree's static mutexes are destroyed at exit; one held then aborts
//! the process, as a loaded host showed at shutdown).

use std::collections::VecDeque;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};

type Task = Box<dyn FnOnce() + Send + 'static>;

/// The queue the lanes take tasks from; at most one task per session is
/// ever in it (see `state`), so its length is bounded by the session cap.
#[derive(Default)]
struct Lanes {
    tasks: Mutex<VecDeque<Task>>,
    ready: Condvar,
}

pub struct Compute {
    shared: rayon::ThreadPool,
    lanes: Arc<Lanes>,
    threads: usize,
    /// Tasks handed over and not yet finished (captures dropped).
    live: Arc<AtomicUsize>,
}

/// Counts a task as finished when dropped: after the task's closure, and
/// everything it captured, has been dropped (also when it panics).
struct Finished(Arc<AtomicUsize>);

impl Drop for Finished {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::SeqCst);
    }
}

impl Compute {
    pub fn new(threads: usize) -> Result<Compute, String> {
        let threads = threads.max(1);
        let shared = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .thread_name(|i| format!("omcl-step-{i}"))
            .build()
            .map_err(|e| format!("compute pool: {e}"))?;
        let lanes = Arc::new(Lanes::default());
        for i in 0..threads {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .thread_name(move |_| format!("omcl-lane-{i}"))
                .build()
                .map_err(|e| format!("compute lane {i}: {e}"))?;
            let lanes = lanes.clone();
            std::thread::Builder::new()
                .name(format!("omcl-lane-{i}-feed"))
                .spawn(move || {
                    loop {
                        let task = {
                            let mut q = lanes.tasks.lock().unwrap_or_else(|e| e.into_inner());
                            loop {
                                if let Some(t) = q.pop_front() {
                                    break t;
                                }
                                q = lanes.ready.wait(q).unwrap_or_else(|e| e.into_inner());
                            }
                        };
                        pool.install(task);
                    }
                })
                .map_err(|e| format!("compute lane {i}: {e}"))?;
        }
        Ok(Compute {
            shared,
            lanes,
            threads,
            live: Arc::default(),
        })
    }

    /// Tasks handed to the pool that have not finished yet, what they
    /// captured included.
    pub fn running(&self) -> usize {
        self.live.load(Ordering::SeqCst)
    }

    /// `f`, counted in [`Compute::running`] from now until it has run and
    /// been dropped.
    fn counted(&self, f: impl FnOnce() + Send + 'static) -> impl FnOnce() + Send + 'static {
        self.live.fetch_add(1, Ordering::SeqCst);
        let done = Finished(self.live.clone());
        move || {
            let _done = done;
            // `f` is consumed by the call: its captures are dropped when
            // it returns, before `_done`.
            f();
        }
    }

    pub fn threads(&self) -> usize {
        self.threads
    }

    /// Runs `f` on the shared pool: all threads on one task.
    pub fn spawn_shared(&self, f: impl FnOnce() + Send + 'static) {
        self.shared.spawn(self.counted(f));
    }

    /// Runs `f` whole on the next free lane, in arrival order.
    pub fn spawn_lane(&self, f: impl FnOnce() + Send + 'static) {
        let f = self.counted(f);
        let mut q = self.lanes.tasks.lock().unwrap_or_else(|e| e.into_inner());
        q.push_back(Box::new(f));
        drop(q);
        self.lanes.ready.notify_one();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::mpsc;

    #[test]
    fn lanes_run_parallel_loops_on_one_thread_and_the_shared_pool_on_all() {
        use rayon::prelude::*;
        let c = Compute::new(2).unwrap();
        let (tx, rx) = mpsc::channel();
        let t = tx.clone();
        c.spawn_lane(move || {
            t.send(("lane", rayon::current_num_threads())).unwrap();
            // A parallel loop inside a lane stays on the lane's thread.
            let me = std::thread::current().id();
            let all_here = (0..1000)
                .into_par_iter()
                .all(|_| std::thread::current().id() == me);
            t.send(("lane-loop-here", all_here as usize)).unwrap();
        });
        c.spawn_shared(move || {
            tx.send(("shared", rayon::current_num_threads())).unwrap();
        });
        let mut got: Vec<_> = (0..3).map(|_| rx.recv().unwrap()).collect();
        got.sort();
        assert_eq!(got, vec![("lane", 1), ("lane-loop-here", 1), ("shared", 2)]);
    }

    /// Sets its flag when dropped, slowly (as releasing a map's scene is).
    struct SlowDrop(Arc<AtomicUsize>);

    impl Drop for SlowDrop {
        fn drop(&mut self) {
            std::thread::sleep(std::time::Duration::from_millis(150));
            self.0.fetch_add(1, Ordering::SeqCst);
        }
    }

    #[test]
    fn a_task_runs_until_what_it_captured_is_dropped() {
        let c = Compute::new(2).unwrap();
        let dropped = Arc::new(AtomicUsize::new(0));
        let (tx, rx) = mpsc::channel();
        for shared in [true, false] {
            let held = SlowDrop(dropped.clone());
            let tx = tx.clone();
            let task = move || {
                let _keep = &held;
                // Answered before the captures are dropped, as a step is.
                tx.send(()).unwrap();
            };
            if shared {
                c.spawn_shared(task);
            } else {
                c.spawn_lane(task);
            }
        }
        assert_eq!(c.running(), 2);
        rx.recv().unwrap();
        rx.recv().unwrap();
        let t0 = std::time::Instant::now();
        while c.running() > 0 {
            // A hang guard, not a time bound.
            assert!(t0.elapsed().as_secs() < 60, "tasks never finished");
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        // Both answered long before; counted until their captures went.
        assert_eq!(dropped.load(Ordering::SeqCst), 2);
    }
}
