//! Results that arrive a few frames after they were asked for (asynchronous GPU readbacks:
//! captures, resampling counts), each tagged by whoever asked, taken by tag in any order.

use std::sync::{Arc, Mutex};

/// A shared list of tagged results: the render side pushes, the asking side takes.
pub struct Tagged<T>(Arc<Mutex<Vec<(u32, T)>>>);

impl<T> Default for Tagged<T> {
    fn default() -> Self {
        Tagged(Arc::default())
    }
}

impl<T> Clone for Tagged<T> {
    fn clone(&self) -> Self {
        Tagged(self.0.clone())
    }
}

impl<T> Tagged<T> {
    /// Hand in the result tagged `tag`.
    pub fn push(&self, tag: u32, value: T) {
        if let Ok(mut got) = self.0.lock() {
            got.push((tag, value));
        }
    }

    /// Whether the result tagged `tag` arrived.
    pub fn has(&self, tag: u32) -> bool {
        self.0
            .lock()
            .is_ok_and(|got| got.iter().any(|(t, _)| *t == tag))
    }

    /// The result tagged `tag`, once it arrived.
    pub fn take(&self, tag: u32) -> Option<T> {
        let mut got = self.0.lock().ok()?;
        let i = got.iter().position(|(t, _)| *t == tag)?;
        Some(got.swap_remove(i).1)
    }

    /// Every result that arrived, with its tag, in the order they arrived.
    pub fn take_all(&self) -> Vec<(u32, T)> {
        self.0
            .lock()
            .map(|mut got| std::mem::take(&mut *got))
            .unwrap_or_default()
    }
}
