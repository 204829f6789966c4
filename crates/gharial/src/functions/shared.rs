//! Data shared by the models of one stage.
//!
//! Some models of a stage depend on the same expensive computation at the same point:
//! the contact dynamics of a legged robot give its dynamics, the contact forces a cost
//! tracks and the forces its friction cones constrain. Such models keep that computation
//! in one data object per stage data instead of one each: while
//! [`StageData::new`](crate::problem::StageData::new) creates a stage's data (inside
//! [`with_shared_data`]), [`shared_data`] hands every model that asks with the same key
//! (e.g. the address of the shared sub-model) and type the same object. Outside such a
//! scope every call creates a fresh object. The shared object memoises by its input, so
//! that sharing changes no result, only how often it is computed.

use std::any::Any;
use std::cell::RefCell;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

type Entry = (usize, Arc<dyn Any + Send + Sync>);

thread_local! {
    static SCOPE: RefCell<Option<Vec<Entry>>> = const { RefCell::new(None) };
}

/// Restores the enclosing scope when a [`with_shared_data`] call ends (also by panic).
struct ScopeGuard(Option<Vec<Entry>>);

impl Drop for ScopeGuard {
    fn drop(&mut self) {
        let outer = self.0.take();
        SCOPE.with(|s| *s.borrow_mut() = outer);
    }
}

/// Runs `f` with a fresh scope of shared data objects (the data created in `f` share
/// what they ask for by key).
pub fn with_shared_data<R>(f: impl FnOnce() -> R) -> R {
    let outer = SCOPE.with(|s| s.borrow_mut().replace(Vec::new()));
    let _guard = ScopeGuard(outer);
    f()
}

/// The object of the current scope for `key` and type `T`, created by `make` the first
/// time (or every time outside a scope).
pub fn shared_data<T: Send + 'static>(key: usize, make: impl FnOnce() -> T) -> Arc<Mutex<T>> {
    let found = SCOPE.with(|s| {
        let scope = s.borrow();
        scope.as_ref().and_then(|entries| {
            entries
                .iter()
                .filter(|(k, _)| *k == key)
                .find_map(|(_, v)| v.clone().downcast::<Mutex<T>>().ok())
        })
    });
    if let Some(v) = found {
        return v;
    }
    let v = Arc::new(Mutex::new(make()));
    SCOPE.with(|s| {
        if let Some(entries) = s.borrow_mut().as_mut() {
            entries.push((key, v.clone()));
        }
    });
    v
}

/// Locks a shared data object (a panic of an earlier holder leaves the data usable: it
/// memoises by input and recomputes what it does not hold).
pub fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn objects_are_shared_by_key_and_type_within_a_scope_only() {
        let (a, b, c, d) = with_shared_data(|| {
            (
                shared_data(1, || 1.0_f64),
                shared_data(1, || 2.0_f64),
                shared_data(2, || 3.0_f64),
                shared_data(1, || 4_u32),
            )
        });
        assert!(Arc::ptr_eq(&a, &b));
        assert_eq!(*lock(&b), 1.0);
        assert!(!Arc::ptr_eq(&a, &c));
        assert_eq!(*lock(&d), 4);
        let e = with_shared_data(|| shared_data(1, || 5.0_f64));
        assert_eq!(*lock(&e), 5.0);
        let (f, g) = (shared_data(1, || 6.0_f64), shared_data(1, || 7.0_f64));
        assert!(!Arc::ptr_eq(&f, &g));
    }
}
