//! A slot of capacity one where the latest request wins.
//!
//! Producers [`Latest::post`] jobs; one consumer [`Latest::take`]s them. A job posted while an
//! earlier one still waits replaces it, and the replaced job is returned to its poster, who
//! answers it as superseded. So at most one job waits per slot, whatever the request rate: a
//! viewer that drags the camera gets the newest view next, never a backlog of stale ones.

use std::sync::{Condvar, Mutex, PoisonError};
use std::time::{Duration, Instant};

/// What [`Latest::take_timeout`] got.
#[derive(Debug, PartialEq, Eq)]
pub enum Taken<T> {
    /// A job.
    Job(T),
    /// No job within the time.
    Timeout,
    /// The slot is closed and empty.
    Closed,
}

/// The slot; see the module docs.
#[derive(Debug)]
pub struct Latest<T> {
    state: Mutex<State<T>>,
    ready: Condvar,
}

#[derive(Debug)]
struct State<T> {
    pending: Option<T>,
    closed: bool,
}

impl<T> Default for Latest<T> {
    fn default() -> Self {
        Self {
            state: Mutex::new(State {
                pending: None,
                closed: false,
            }),
            ready: Condvar::new(),
        }
    }
}

impl<T> Latest<T> {
    /// An empty, open slot.
    pub fn new() -> Self {
        Self::default()
    }

    /// Puts `job` in the slot; returns the job it replaced, if one was waiting. After
    /// [`Latest::close`] the job itself comes back.
    pub fn post(&self, job: T) -> Option<T> {
        let mut state = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        if state.closed {
            return Some(job);
        }
        let replaced = state.pending.replace(job);
        self.ready.notify_one();
        replaced
    }

    /// Waits for a job; `None` once the slot is closed and empty.
    pub fn take(&self) -> Option<T> {
        let mut state = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        loop {
            if let Some(job) = state.pending.take() {
                return Some(job);
            }
            if state.closed {
                return None;
            }
            state = self
                .ready
                .wait(state)
                .unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// Waits at most `timeout` for a job.
    pub fn take_timeout(&self, timeout: Duration) -> Taken<T> {
        let deadline = Instant::now() + timeout;
        let mut state = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        loop {
            if let Some(job) = state.pending.take() {
                return Taken::Job(job);
            }
            if state.closed {
                return Taken::Closed;
            }
            let now = Instant::now();
            if now >= deadline {
                return Taken::Timeout;
            }
            state = self
                .ready
                .wait_timeout(state, deadline - now)
                .unwrap_or_else(PoisonError::into_inner)
                .0;
        }
    }

    /// Closes the slot: a waiting job is still taken, then [`Latest::take`] returns `None`.
    pub fn close(&self) {
        let mut state = self.state.lock().unwrap_or_else(PoisonError::into_inner);
        state.closed = true;
        self.ready.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn a_newer_job_replaces_a_waiting_one() {
        let slot = Latest::new();
        assert_eq!(slot.post(1), None);
        assert_eq!(slot.post(2), Some(1));
        assert_eq!(slot.post(3), Some(2));
        assert_eq!(slot.take(), Some(3));
        assert_eq!(slot.post(4), None);
        assert_eq!(slot.take(), Some(4));
    }

    #[test]
    fn take_timeout_times_out_then_takes() {
        let slot = Latest::new();
        assert_eq!(slot.take_timeout(Duration::from_millis(5)), Taken::Timeout);
        slot.post(1);
        assert_eq!(slot.take_timeout(Duration::from_millis(5)), Taken::Job(1));
        slot.close();
        assert_eq!(slot.take_timeout(Duration::from_millis(5)), Taken::Closed);
    }

    #[test]
    fn take_waits_for_a_job_and_close_ends_it() {
        let slot = Arc::new(Latest::new());
        let consumer = {
            let slot = Arc::clone(&slot);
            std::thread::spawn(move || {
                let mut got = Vec::new();
                while let Some(j) = slot.take() {
                    got.push(j);
                }
                got
            })
        };
        slot.post(7);
        // Whether or not the consumer took 7 already, 8 is delivered or replaces 7.
        let replaced = slot.post(8);
        slot.close();
        assert_eq!(slot.post(9), Some(9), "a closed slot refuses jobs");
        let got = consumer.join().unwrap();
        assert_eq!(got.last(), Some(&8));
        match replaced {
            Some(7) => assert_eq!(got, vec![8]),
            None => assert_eq!(got, vec![7, 8]),
            other => panic!("{other:?}"),
        }
    }
}
