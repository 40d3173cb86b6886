//! envis's compile thread: a queue of jobs run in order on a thread of its own, and the slot
//! each job fills ([`Compiled`]).

use super::Program;
use bevy::prelude::*;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, OnceLock};

/// A program compiled on envis's thread: empty until it is, then the program or why it failed.
pub struct Compiled<T>(Arc<CompiledInner<T>>);

struct CompiledInner<T> {
    result: OnceLock<Result<T, String>>,
    /// Set when its job is queued (once).
    queued: AtomicBool,
}

impl<T> Clone for Compiled<T> {
    fn clone(&self) -> Self {
        Compiled(self.0.clone())
    }
}

impl<T> Default for Compiled<T> {
    fn default() -> Self {
        Compiled(Arc::new(CompiledInner {
            result: OnceLock::new(),
            queued: AtomicBool::new(false),
        }))
    }
}

impl<T> Compiled<T> {
    /// The program, once compiled (`None` while it compiles and where it failed).
    pub fn get(&self) -> Option<&T> {
        self.0.result.get()?.as_ref().ok()
    }

    /// Whether compiling it has ended, well or not.
    pub fn done(&self) -> bool {
        self.0.result.get().is_some()
    }

    /// Why it failed, once it has.
    pub fn error(&self) -> Option<&str> {
        self.0.result.get()?.as_ref().err().map(String::as_str)
    }

    /// Block until it has been compiled.
    pub(super) fn wait(&self) -> Option<&T> {
        self.0.result.wait().as_ref().ok()
    }

    pub(super) fn set(&self, result: Result<T, String>) {
        let _ = self.0.result.set(result);
    }

    /// `true` the first time only: the caller queues its job.
    pub(super) fn first_queued(&self) -> bool {
        !self.0.queued.swap(true, Ordering::AcqRel)
    }
}

struct Job {
    program: Program,
    run: Box<dyn FnOnce() + Send>,
}

#[derive(Default)]
struct Queue {
    jobs: VecDeque<Job>,
    closed: bool,
}

/// envis's compile thread and its queue of jobs, run in order (a job a frame asks for first).
pub(super) struct Worker {
    queue: Arc<(Mutex<Queue>, Condvar)>,
    /// `false` where no thread could be started: jobs then run where they are queued.
    threaded: bool,
}

impl Worker {
    pub(super) fn start() -> Self {
        let queue: Arc<(Mutex<Queue>, Condvar)> = Arc::default();
        let q = queue.clone();
        let threaded = std::thread::Builder::new()
            .name("envis compile".into())
            .spawn(move || run_jobs(&q))
            .inspect_err(|e| warn!("envis: no compile thread ({e}): compiling on the frame path"))
            .is_ok();
        Worker { queue, threaded }
    }

    pub(super) fn push(&self, program: Program, run: impl FnOnce() + Send + 'static) {
        if !self.threaded {
            return run();
        }
        let (lock, wake) = &*self.queue;
        if let Ok(mut q) = lock.lock() {
            q.jobs.push_back(Job {
                program,
                run: Box::new(run),
            });
            wake.notify_one();
        }
    }

    /// Move `program`'s job, if it still waits, to the front of the queue.
    pub(super) fn hurry(&self, program: Program) {
        let Ok(mut q) = self.queue.0.lock() else {
            return;
        };
        if let Some(i) = q.jobs.iter().position(|j| j.program == program)
            && i > 0
            && let Some(job) = q.jobs.remove(i)
        {
            q.jobs.push_front(job);
        }
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        if let Ok(mut q) = self.queue.0.lock() {
            q.closed = true;
            q.jobs.clear();
        }
        self.queue.1.notify_all();
    }
}

/// The compile thread's loop: one job at a time until the queue is closed.
fn run_jobs(queue: &(Mutex<Queue>, Condvar)) {
    let (lock, wake) = queue;
    loop {
        let job = {
            let Ok(mut q) = lock.lock() else { return };
            loop {
                if q.closed {
                    return;
                }
                if let Some(job) = q.jobs.pop_front() {
                    break job;
                }
                q = match wake.wait(q) {
                    Ok(q) => q,
                    Err(_) => return,
                };
            }
        };
        // A job that panics outside `checked` must not end the thread (its slot stays empty,
        // and is logged).
        let program = job.program;
        if let Err(panic) = std::panic::catch_unwind(std::panic::AssertUnwindSafe(job.run)) {
            error!(
                "envis: compiling {program:?} panicked: {}",
                panic_message(&panic)
            );
        }
    }
}

/// Run `make` on `device`, a panic turned into an `Err`, so that whoever waits for the program
/// learns that it failed and never waits for ever. No error scope: this build of wgpu keeps one
/// stack of them for all threads, which Bevy's pipeline cache pushes and pops on its own threads
/// (a scope here made both panic: "mismatched pop_error_scope"). Sources that may not compile
/// (an edited lighting pass) are validated before ([`validate_wgsl`]); a device error past that
/// goes to Bevy's handler.
pub(super) fn checked<T>(
    device: &wgpu::Device,
    make: impl FnOnce(&wgpu::Device) -> T,
) -> Result<T, String> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| make(device)))
        .map_err(|panic| format!("compiling panicked: {}", panic_message(&panic)))
}

/// Parse and validate `wgsl` on the CPU (naga, as wgpu would): the error as text.
pub(super) fn validate_wgsl(wgsl: &str) -> Result<(), String> {
    use wgpu::naga;
    let module = naga::front::wgsl::parse_str(wgsl).map_err(|e| e.emit_to_string(wgsl))?;
    let flags = naga::valid::ValidationFlags::all();
    naga::valid::Validator::new(flags, naga::valid::Capabilities::all())
        .validate(&module)
        .map_err(|e| e.emit_to_string(wgsl))?;
    Ok(())
}

/// The text of a panic's payload.
fn panic_message(panic: &Box<dyn std::any::Any + Send>) -> &str {
    (panic.downcast_ref::<&str>().copied())
        .or_else(|| panic.downcast_ref::<String>().map(String::as_str))
        .unwrap_or("(no message)")
}
