//! The WebAssembly adapter: `inkwarp-core` behind a plain C ABI for the browser editor.
//!
//! No engine logic lives here. Every export takes numbers and pointers into the module's
//! linear memory; structured arguments travel as UTF-8 JSON, bulk data (mattes, images,
//! fields) as raw byte / `f32` arrays. The caller allocates with [`iw_alloc`] and frees with
//! [`iw_free`]. Functions that produce JSON (a report, an error, a polyline) leave it in a
//! result buffer read through [`iw_result_ptr`] / [`iw_result_len`], valid until the next
//! call. Status codes: `0` success, `1` error (the result holds `{"error": "..."}`).
//!
//! The plain ABI (rather than wasm-bindgen) keeps the build to `cargo` and the
//! `wasm32-unknown-unknown` target: no code generator to install at the matching version.
//! The TypeScript side is `web/src/engine.ts`.
#![allow(unsafe_code)] // the C ABI needs raw pointers; every unsafe block is a slice view.

mod api;

use std::cell::RefCell;

pub use api::*;

thread_local! {
    static RESULT: RefCell<Vec<u8>> = const { RefCell::new(Vec::new()) };
}

/// Stores `bytes` as the result of the current call.
pub(crate) fn set_result(bytes: Vec<u8>) {
    RESULT.with(|r| *r.borrow_mut() = bytes);
}

/// Stores an error message as `{"error": message}` and returns status 1.
pub(crate) fn fail(message: impl std::fmt::Display) -> i32 {
    let json = serde_json::json!({ "error": message.to_string() });
    set_result(json.to_string().into_bytes());
    1
}

/// Stores a JSON value as the result and returns status 0.
pub(crate) fn ok_json(value: &impl serde::Serialize) -> i32 {
    match serde_json::to_vec(value) {
        Ok(bytes) => {
            set_result(bytes);
            0
        }
        Err(err) => fail(format!("Could not encode the result as JSON: {err}.")),
    }
}

/// Pointer to the result of the last call (JSON, UTF-8).
#[no_mangle]
pub extern "C" fn iw_result_ptr() -> *const u8 {
    RESULT.with(|r| r.borrow().as_ptr())
}

/// Length in bytes of the result of the last call.
#[no_mangle]
pub extern "C" fn iw_result_len() -> usize {
    RESULT.with(|r| r.borrow().len())
}

/// Allocates `len` bytes (8-byte aligned, so `f32`/`f64` views are valid) and returns
/// the pointer; `len == 0` gives a dangling, non-null pointer.
#[no_mangle]
pub extern "C" fn iw_alloc(len: usize) -> *mut u8 {
    let words = len.div_ceil(8);
    let mut v: Vec<u64> = Vec::with_capacity(words);
    let ptr = v.as_mut_ptr() as *mut u8;
    std::mem::forget(v);
    ptr
}

/// Frees memory from [`iw_alloc`]; `len` must be the length it was allocated with.
///
/// # Safety
/// `ptr` must come from `iw_alloc(len)` and not have been freed.
#[no_mangle]
pub unsafe extern "C" fn iw_free(ptr: *mut u8, len: usize) {
    let words = len.div_ceil(8);
    if words > 0 {
        drop(Vec::from_raw_parts(ptr as *mut u64, 0, words));
    }
}

/// A byte slice view of caller memory (`len == 0` or null gives an empty slice).
pub(crate) fn bytes<'a>(ptr: *const u8, len: usize) -> &'a [u8] {
    if ptr.is_null() || len == 0 {
        return &[];
    }
    // SAFETY: the caller passes a region it allocated with `iw_alloc` and filled.
    unsafe { std::slice::from_raw_parts(ptr, len) }
}

/// An `f32` slice view of caller memory.
pub(crate) fn floats<'a>(ptr: *const f32, len: usize) -> &'a [f32] {
    if ptr.is_null() || len == 0 {
        return &[];
    }
    // SAFETY: as for `bytes`; `iw_alloc` returns 8-byte aligned memory.
    unsafe { std::slice::from_raw_parts(ptr, len) }
}

/// A mutable `f32` slice view of caller memory.
pub(crate) fn floats_mut<'a>(ptr: *mut f32, len: usize) -> &'a mut [f32] {
    if ptr.is_null() || len == 0 {
        return &mut [];
    }
    // SAFETY: as for `floats`; the caller does not alias the region during the call.
    unsafe { std::slice::from_raw_parts_mut(ptr, len) }
}

/// A mutable byte slice view of caller memory.
pub(crate) fn bytes_mut<'a>(ptr: *mut u8, len: usize) -> &'a mut [u8] {
    if ptr.is_null() || len == 0 {
        return &mut [];
    }
    // SAFETY: as for `bytes`.
    unsafe { std::slice::from_raw_parts_mut(ptr, len) }
}

/// Parses a JSON argument.
pub(crate) fn json_arg<T: serde::de::DeserializeOwned>(
    ptr: *const u8,
    len: usize,
) -> Result<T, String> {
    serde_json::from_slice(bytes(ptr, len))
        .map_err(|e| format!("The request is not valid JSON for this call: {e}."))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result() -> serde_json::Value {
        let bytes = bytes(iw_result_ptr(), iw_result_len());
        serde_json::from_slice(bytes).unwrap()
    }

    fn put(data: &[u8]) -> (*mut u8, usize) {
        let ptr = iw_alloc(data.len());
        bytes_mut(ptr, data.len()).copy_from_slice(data);
        (ptr, data.len())
    }

    #[test]
    fn allocations_are_aligned_for_floats() {
        for len in [0, 1, 7, 8, 9, 1000] {
            let ptr = iw_alloc(len);
            assert_eq!(ptr as usize % 8, 0);
            // SAFETY: allocated just above with this length.
            unsafe { iw_free(ptr, len) };
        }
    }

    #[test]
    fn a_grid_reports_its_links_and_cuts_break_them() {
        let (cuts, cuts_len) = put(br#"[[[1.5, -1.0], [1.5, 4.0]]]"#);
        let h = iw_grid_new(4, 3, std::ptr::null(), 0, cuts, cuts_len);
        assert!(h > 0);
        let out = iw_alloc(12);
        assert_eq!(iw_grid_links(h, out, 12), 0);
        let links = bytes(out, 12);
        // (0,0): active, right, down; (1,0): active, down, the link to (2,0) is cut.
        assert_eq!(links[0], 0b111);
        assert_eq!(links[1], 0b101);
        // The last column has no right link, the last row no down link.
        assert_eq!(links[3], 0b101);
        assert_eq!(links[8], 0b011);
        iw_grid_free(h);
    }

    #[test]
    fn a_solve_through_the_c_abi_translates_a_single_point() {
        let h = iw_grid_new(16, 12, std::ptr::null(), 0, std::ptr::null(), 0);
        let (req, req_len) =
            put(br#"{"features": [{"kind": "point", "rest": [[5, 5]], "pose": [[7, 4]]}]}"#);
        let n = 16 * 12;
        let field = iw_alloc(8 * n) as *mut f32;
        assert_eq!(iw_solve(h, req, req_len, std::ptr::null(), field), 0);
        let f = floats(field, 2 * n);
        for i in [0, 77, n - 1] {
            assert!((f[i] - 2.0).abs() < 0.05, "dx[{i}] = {}", f[i]);
            assert!((f[n + i] + 1.0).abs() < 0.05, "dy[{i}] = {}", f[n + i]);
        }
        assert_eq!(result()["constrained_nodes"], 1);
        iw_grid_free(h);
    }

    #[test]
    fn errors_come_back_as_json_messages() {
        let (bad, len) = put(b"{not json");
        assert_eq!(iw_curve(bad, len), 1);
        assert!(result()["error"]
            .as_str()
            .unwrap()
            .contains("not valid JSON"));
        assert_eq!(
            iw_grid_new(0, 3, std::ptr::null(), 0, std::ptr::null(), 0),
            0
        );
        assert!(result()["error"]
            .as_str()
            .unwrap()
            .contains("at least 1 pixel"));
        let (req, req_len) = put(br#"{"features": []}"#);
        assert_eq!(
            iw_solve(999, req, req_len, std::ptr::null(), std::ptr::null_mut()),
            1
        );
        assert!(result()["error"]
            .as_str()
            .unwrap()
            .contains("no grid with handle 999"));
    }

    #[test]
    fn keyframes_and_methods_come_from_the_engine() {
        let (req, len) = put(br#"{"rest": [[0, 0]], "keys": [{"t": 0, "points": [[0, 0]], "interpolation": "linear"}, {"t": 2, "points": [[4, 2]]}], "t": 1}"#);
        assert_eq!(iw_points_at(req, len), 0);
        assert_eq!(result(), serde_json::json!([[2.0, 1.0]]));
        assert_eq!(iw_methods(), 0);
        assert_eq!(
            result()[0],
            serde_json::json!({"name": "tps", "available": true})
        );
    }
}
