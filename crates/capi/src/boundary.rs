//! The machinery of the boundary: the guard every function body runs in (a panic becomes
//! `GLINT_PANIC`, an error a status and this thread's last message) and the checked access to
//! the caller's pointers. Every `unsafe` block of the crate that touches a caller's pointer is
//! here, each behind a null check.

use std::cell::RefCell;
use std::panic::{AssertUnwindSafe, catch_unwind};

use crate::types::GlintStatus;

/// Why a call failed: its status and a message naming the argument or parameter.
#[derive(Debug)]
pub(crate) struct Failure {
    status: GlintStatus,
    message: String,
}

impl Failure {
    /// A required pointer argument `name` was NULL.
    pub(crate) fn null(name: &str) -> Self {
        Self {
            status: GlintStatus::GLINT_NULL_POINTER,
            message: format!("`{name}` is NULL"),
        }
    }

    /// An invalid material parameter.
    pub(crate) fn parameter(message: String) -> Self {
        Self {
            status: GlintStatus::GLINT_INVALID_PARAMETER,
            message,
        }
    }

    /// An invalid query argument.
    pub(crate) fn argument(message: String) -> Self {
        Self {
            status: GlintStatus::GLINT_INVALID_ARGUMENT,
            message,
        }
    }

    /// The status it returns.
    pub(crate) fn status(&self) -> GlintStatus {
        self.status
    }

    /// The same failure, said of row `i` of a batch.
    pub(crate) fn in_row(self, i: usize) -> Self {
        Self {
            status: self.status,
            message: format!("row {i}: {}", self.message),
        }
    }
}

thread_local! {
    /// The message of this thread's last call, NUL-terminated; empty after a success.
    static LAST_ERROR: RefCell<Vec<u8>> = RefCell::new(vec![0]);
}

/// Replaces this thread's message. Never panics: a thread being torn down keeps no message.
fn set_last_error(message: &str) {
    let _ = LAST_ERROR.try_with(|cell| {
        if let Ok(mut buffer) = cell.try_borrow_mut() {
            buffer.clear();
            // An interior NUL would cut the C string short; none of glint's messages has one.
            buffer.extend(message.bytes().filter(|&b| b != 0));
            buffer.push(0);
        }
    });
}

/// This thread's last message as a NUL-terminated string: valid until the thread's next call
/// of a function that sets it, or the thread's end.
pub(crate) fn last_error() -> *const u8 {
    LAST_ERROR
        .try_with(|cell| cell.try_borrow().map(|buffer| buffer.as_ptr()).ok())
        .ok()
        .flatten()
        .unwrap_or(c"".as_ptr().cast())
}

/// Runs the body of the C function `function`: `GLINT_OK` and an empty message on success;
/// the failure's status and message, prefixed with `function`, otherwise. A panic is caught
/// here and becomes `GLINT_PANIC`, so none crosses the boundary.
///
/// The body is asserted unwind-safe: after a panic the caller's material is intact (it is
/// never mutated after construction), and a scratch left mid-query is replaced on its next use
/// (`GlintScratch::in_query`).
pub(crate) fn guard(function: &str, body: impl FnOnce() -> Result<(), Failure>) -> GlintStatus {
    match catch_unwind(AssertUnwindSafe(body)) {
        Ok(Ok(())) => {
            set_last_error("");
            GlintStatus::GLINT_OK
        }
        Ok(Err(failure)) => {
            set_last_error(&format!("{function}: {}", failure.message));
            failure.status
        }
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .copied()
                .or_else(|| payload.downcast_ref::<String>().map(String::as_str))
                .unwrap_or("a panic without a message");
            set_last_error(&format!(
                "{function}: internal error, glint panicked (please report it): {what}"
            ));
            // Dropping a payload may panic in turn (its Drop is arbitrary); catch that too.
            let _ = catch_unwind(AssertUnwindSafe(|| drop(payload)));
            GlintStatus::GLINT_PANIC
        }
    }
}

/// Fails unless `pointer` is non-NULL.
pub(crate) fn non_null<T>(pointer: *const T, name: &str) -> Result<(), Failure> {
    if pointer.is_null() {
        Err(Failure::null(name))
    } else {
        Ok(())
    }
}

/// Reads a `T` the caller passed by pointer.
///
/// # Safety
/// `pointer` is NULL or points to a readable, aligned, initialized `T`.
pub(crate) unsafe fn read<T: Copy>(pointer: *const T, name: &str) -> Result<T, Failure> {
    non_null(pointer, name)?;
    // SAFETY: non-NULL (checked above); readable, aligned and initialized by the contract.
    Ok(unsafe { pointer.read() })
}

/// Reads `N` doubles the caller passed as a `const double*`.
///
/// # Safety
/// `pointer` is NULL or points to `N` readable doubles.
pub(crate) unsafe fn read_array<const N: usize>(
    pointer: *const f64,
    name: &str,
) -> Result<[f64; N], Failure> {
    // SAFETY: `[f64; N]` has the size of N doubles and the alignment of one; the contract
    // makes N doubles readable there.
    unsafe { read(pointer.cast::<[f64; N]>(), name) }
}

/// `Ok` when an array of `n` values of `T` could exist (at most `isize::MAX` bytes, Rust's and
/// C's bound on one object): a larger `n` is a caller's mistake, refused before any use.
fn fits_in_memory<T>(n: usize, name: &str) -> Result<(), Failure> {
    let fits = n
        .checked_mul(std::mem::size_of::<T>())
        .is_some_and(|bytes| bytes <= isize::MAX as usize);
    if fits {
        Ok(())
    } else {
        Err(Failure::argument(format!(
            "`{name}`: an array of {n} values of {} bytes is larger than memory can hold (check `n`)",
            std::mem::size_of::<T>()
        )))
    }
}

/// The caller's array of `n` values of `T` as a slice (empty for `n` = 0, where the pointer may
/// be NULL).
///
/// # Safety
/// `pointer` is NULL or points to `n` readable, aligned, initialized values of `T` that
/// nothing writes during the call.
pub(crate) unsafe fn read_slice<'a, T>(
    pointer: *const T,
    n: usize,
    name: &str,
) -> Result<&'a [T], Failure> {
    if n == 0 {
        return Ok(&[]);
    }
    non_null(pointer, name)?;
    fits_in_memory::<T>(n, name)?;
    // SAFETY: non-NULL (checked above); n readable values by the contract.
    Ok(unsafe { std::slice::from_raw_parts(pointer, n) })
}

/// The caller's writable array of `n` values of `T` (empty for `n` = 0, where the pointer may
/// be NULL). The values may be uninitialized: write them with [`std::slice::IterMut`] and
/// `ptr::write`-like assignment of types without `Drop` only.
///
/// # Safety
/// `pointer` is NULL or points to writable, aligned memory for `n` values of `T` that nothing
/// else reads or writes during the call.
pub(crate) unsafe fn write_slice<'a, T: Copy>(
    pointer: *mut T,
    n: usize,
    name: &str,
) -> Result<&'a mut [std::mem::MaybeUninit<T>], Failure> {
    if n == 0 {
        return Ok(&mut []);
    }
    non_null(pointer, name)?;
    fits_in_memory::<T>(n, name)?;
    // SAFETY: non-NULL (checked above); writable for n values and used by this call alone,
    // by the contract; `MaybeUninit` makes no claim that the memory is initialized.
    Ok(unsafe { std::slice::from_raw_parts_mut(pointer.cast(), n) })
}

/// The caller's object behind a `const` handle.
///
/// # Safety
/// `pointer` is NULL or a live handle from this library, not being freed concurrently.
pub(crate) unsafe fn shared<'a, T>(pointer: *const T, name: &str) -> Result<&'a T, Failure> {
    non_null(pointer, name)?;
    // SAFETY: non-NULL (checked above); a live object by the contract, only read through this
    // reference.
    Ok(unsafe { &*pointer })
}

/// The caller's object behind a mutable handle.
///
/// # Safety
/// `pointer` is NULL or a live handle from this library that no other thread or reference
/// uses during the call.
pub(crate) unsafe fn exclusive<'a, T>(pointer: *mut T, name: &str) -> Result<&'a mut T, Failure> {
    non_null(pointer, name)?;
    // SAFETY: non-NULL (checked above); live and used by this call alone, by the contract.
    Ok(unsafe { &mut *pointer })
}

/// Takes back and drops an object the library handed out with `Box::into_raw`; NULL is a
/// no-op.
///
/// # Safety
/// `pointer` is NULL or came from `Box::into_raw` in this library, is not used afterwards and
/// not freed twice.
pub(crate) unsafe fn free<T>(pointer: *mut T) {
    if !pointer.is_null() {
        // SAFETY: from `Box::into_raw` and given back once, by the contract.
        drop(unsafe { Box::from_raw(pointer) });
    }
}

/// Writes a result through an out-pointer already checked with [`non_null`].
///
/// # Safety
/// `pointer` is non-NULL and points to writable, aligned memory for a `T`.
pub(crate) unsafe fn write<T>(pointer: *mut T, value: T) {
    // SAFETY: the contract above; `write` drops no previous value (the memory may be
    // uninitialized, and the types written hold nothing to drop).
    unsafe { pointer.write(value) }
}

#[cfg(test)]
mod tests {
    use std::ffi::CStr;

    use super::*;

    fn message() -> String {
        // SAFETY: `last_error` returns a NUL-terminated string valid until the next call here.
        unsafe { CStr::from_ptr(last_error().cast()) }
            .to_string_lossy()
            .into_owned()
    }

    #[test]
    fn a_panic_in_a_body_becomes_glint_panic_with_its_message() {
        // No input reaches a panic in glint-brdf (its validation suites find none), so the
        // guard is tested with a body that panics by construction.
        let status = guard("glint_test", || panic!("deliberate"));
        assert_eq!(status, GlintStatus::GLINT_PANIC);
        assert!(message().starts_with("glint_test: internal error"));
        assert!(message().ends_with("deliberate"));
        let status = guard("glint_test", || panic!("{}", String::from("formatted")));
        assert_eq!(status, GlintStatus::GLINT_PANIC);
        assert!(message().ends_with("formatted"));
    }

    #[test]
    fn success_clears_the_message_and_failures_keep_their_status() {
        let status = guard("glint_test", || Err(Failure::argument("bad `wi`".into())));
        assert_eq!(status, GlintStatus::GLINT_INVALID_ARGUMENT);
        assert_eq!(message(), "glint_test: bad `wi`");
        assert_eq!(guard("glint_test", || Ok(())), GlintStatus::GLINT_OK);
        assert_eq!(message(), "");
    }
}
