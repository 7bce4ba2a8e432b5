//! The WebAssembly adapter: `inkwarp-core` behind a plain C ABI for the browser editor.
//!
//! No engine logic lives here, with one exception: `draft.rs` rasterises the editor's
//! WebGL2 draft and fast full frames on the CPU (for a software GPU), to the GPU's 8-bit
//! rounding, which the core's `f32` renderer does not follow. Every export takes numbers
//! and pointers into the module's linear memory; structured arguments travel as UTF-8
//! JSON, bulk data (mattes, images, fields) as raw byte / `f32` arrays. The caller
//! allocates with [`iw_alloc`] and frees with [`iw_free`]. Functions that produce JSON (a
//! report, an error, a polyline) leave it in a result buffer read through
//! [`iw_result_ptr`] / [`iw_result_len`], valid until the next call. Status codes: `0`
//! success, `1` error (the result holds `{"error": "..."}`).
//!
//! The plain ABI (rather than wasm-bindgen) keeps the build to `cargo` and the
//! `wasm32-unknown-unknown` target: no code generator to install at the matching version.
//! The TypeScript side is `web/src/engine.ts`.
#![allow(unsafe_code)] // the C ABI needs raw pointers; every unsafe block is a slice view.

mod api;
mod draft;

use std::cell::RefCell;

pub use api::*;
pub use draft::*;

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

/// The message of the last panic (a bug in the engine), kept apart from the result buffer:
/// a trap leaves the module's own borrows behind, so the page reads it with
/// [`iw_panic_ptr`] / [`iw_panic_len`] and then starts a fresh instance.
static PANIC: std::sync::Mutex<Vec<u8>> = std::sync::Mutex::new(Vec::new());

/// Installs the hook that records panic messages (call once after instantiating).
#[no_mangle]
pub extern "C" fn iw_init() {
    std::panic::set_hook(Box::new(|info| {
        if let Ok(mut last) = PANIC.lock() {
            *last = info.to_string().into_bytes();
        }
    }));
}

/// Pointer to the message of the last panic (UTF-8; empty when there was none).
#[no_mangle]
pub extern "C" fn iw_panic_ptr() -> *const u8 {
    PANIC.lock().map_or(std::ptr::null(), |m| m.as_ptr())
}

/// Length in bytes of the message of the last panic.
#[no_mangle]
pub extern "C" fn iw_panic_len() -> usize {
    PANIC.lock().map_or(0, |m| m.len())
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

/// A slice view of caller memory (`len == 0` or null gives an empty slice).
pub(crate) fn view<'a, T>(ptr: *const T, len: usize) -> &'a [T] {
    if ptr.is_null() || len == 0 {
        return &[];
    }
    // SAFETY: the caller passes a region it allocated with `iw_alloc` (8-byte aligned) and
    // filled with `len` values of `T`.
    unsafe { std::slice::from_raw_parts(ptr, len) }
}

/// A mutable slice view of caller memory.
pub(crate) fn view_mut<'a, T>(ptr: *mut T, len: usize) -> &'a mut [T] {
    if ptr.is_null() || len == 0 {
        return &mut [];
    }
    // SAFETY: as for `view`; the caller does not alias the region during the call.
    unsafe { std::slice::from_raw_parts_mut(ptr, len) }
}

/// Stores `value` in the first free slot of `store`; its handle (≥ 1).
pub(crate) fn insert<T>(store: &mut Vec<Option<T>>, value: T) -> u32 {
    if let Some(i) = store.iter().position(Option::is_none) {
        store[i] = Some(value);
        return i as u32 + 1;
    }
    store.push(Some(value));
    store.len() as u32
}

/// The value under `handle` in `store`, if there is one.
pub(crate) fn slot<T>(store: &[Option<T>], handle: u32) -> Option<&T> {
    store.get((handle as usize).wrapping_sub(1)).and_then(Option::as_ref)
}

/// The same, to change.
pub(crate) fn slot_mut<T>(store: &mut [Option<T>], handle: u32) -> Option<&mut T> {
    store.get_mut((handle as usize).wrapping_sub(1)).and_then(Option::as_mut)
}

/// Frees the slot of `handle` in `store` (nothing when there is none).
pub(crate) fn release<T>(store: &mut [Option<T>], handle: u32) {
    if let Some(slot) = store.get_mut((handle as usize).wrapping_sub(1)) {
        *slot = None;
    }
}

/// Parses a JSON argument.
pub(crate) fn json_arg<T: serde::de::DeserializeOwned>(
    ptr: *const u8,
    len: usize,
) -> Result<T, String> {
    serde_json::from_slice(view(ptr, len))
        .map_err(|e| format!("The request is not valid JSON for this call: {e}."))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn result() -> serde_json::Value {
        let bytes = view(iw_result_ptr(), iw_result_len());
        serde_json::from_slice(bytes).unwrap()
    }

    fn put(data: &[u8]) -> (*mut u8, usize) {
        let ptr = iw_alloc(data.len());
        view_mut(ptr, data.len()).copy_from_slice(data);
        (ptr, data.len())
    }

    /// Solves `req` on grid `handle` into `out`, asserting that it succeeds (`what` names
    /// the case in the message); returns the report.
    fn solve_ok(handle: u32, req: &serde_json::Value, out: *mut f32, what: &str) -> serde_json::Value {
        let (req, req_len) = put(req.to_string().as_bytes());
        assert_eq!(iw_solve(handle, req, req_len, std::ptr::null(), out), 0, "{what}: {}", result());
        result()
    }

    #[test]
    fn a_frame_drawn_from_a_kept_picture_is_the_solve_then_the_draw() {
        // A cut, a posed point and a held corner at grid step 2: drawn in one call from a
        // kept picture, the same pixels as the field solved out and drawn back in.
        let (w, h) = (24, 18);
        let n = w * h;
        let (cuts, cuts_len) = put(b"[[[12.5, 2], [12.5, 15]]]");
        let grid = iw_grid_new(w, h, std::ptr::null(), 0, cuts, cuts_len);
        let rgba: Vec<u8> = (0..4 * n).map(|i| if i % 4 == 3 { 255 } else { (i * 37 % 251) as u8 }).collect();
        let (img_ptr, _) = put(&rgba);
        let image = iw_image_new(img_ptr, w, h);
        assert!(image > 0);
        let req = serde_json::json!({"features": [
            {"kind": "point", "rest": [[6, 6]], "pose": [[9, 5]]},
            {"kind": "point", "rest": [[20, 14]], "pose": [[20, 14]]}],
            "options": {"grid_step": 2}});
        let field = iw_alloc(8 * n) as *mut f32;
        solve_ok(grid, &req, field, "solve");
        let read = |canvas: u32| {
            let out = iw_alloc(4 * n);
            assert_eq!(iw_canvas_read(canvas, out, 4 * n), 0, "{}", result());
            view(out, 4 * n).to_vec()
        };
        let a = iw_canvas_new(w, h, 10, 20, 30, 255);
        assert_eq!(iw_canvas_draw(a, grid, img_ptr, field, 0.5, -1.0), 0, "{}", result());
        let b = iw_canvas_new(w, h, 10, 20, 30, 255);
        let (r, r_len) = put(req.to_string().as_bytes());
        assert_eq!(iw_grid_solve_kept(grid, r, r_len), 0, "{}", result());
        assert_eq!(result()["constrained_nodes"].as_u64().map(|c| c > 0), Some(true));
        assert_eq!(iw_canvas_draw_solved(b, grid, image, 0.5, -1.0), 0, "{}", result());
        assert_eq!(read(a), read(b));
        // The same frame drawn band by band straight into RGBA8 (`iw_frame_draw`), whole
        // and in two parts cut at row 7, from the field kept again.
        let frame = |rows: Option<[usize; 2]>| {
            assert_eq!(iw_grid_solve_kept(grid, r, r_len), 0, "{}", result());
            let [first, end] = rows.unwrap_or([0, h]);
            let len = 4 * w * (end - first);
            let fr = serde_json::json!({"width": w, "height": h, "background": [10, 20, 30, 255], "rows": rows,
                "layers": [{"grid": grid, "image": image, "offset": [0.5, -1.0]}]});
            let (f, f_len) = put(fr.to_string().as_bytes());
            let out = iw_alloc(len);
            assert_eq!(iw_frame_draw(f, f_len, out, len), 0, "{}", result());
            view(out, len).to_vec()
        };
        assert_eq!(frame(None), read(a));
        assert_eq!([frame(Some([0, 7])), frame(Some([7, h]))].concat(), read(a));
        // A view (`iw_view_draw`) reads the kept field and leaves it: at shrink 1 a region
        // is the frame's, drawn twice from one solve; at shrink 2 it is the smaller frame.
        assert_eq!(iw_grid_solve_kept(grid, r, r_len), 0, "{}", result());
        let view_of = |shrink: usize, region: [usize; 4], rest: bool| {
            let len = 4 * (region[2] - region[0]) * (region[3] - region[1]);
            let vr = serde_json::json!({"width": w, "height": h, "background": [10, 20, 30, 255], "shrink": shrink, "region": region,
                "layers": [{"grid": grid, "image": image, "offset": [0.5, -1.0], "rest": rest}]});
            let (f, f_len) = put(vr.to_string().as_bytes());
            let out = iw_alloc(len);
            assert_eq!(iw_view_draw(f, f_len, out, len), 0, "{}", result());
            view(out, len).to_vec()
        };
        let whole = read(a);
        let want: Vec<u8> = (3..9).flat_map(|y| whole[4 * (y * w + 2)..4 * (y * w + 20)].to_vec()).collect();
        assert_eq!(view_of(1, [2, 3, 20, 9], false), want);
        assert_eq!(view_of(1, [2, 3, 20, 9], false), want);
        assert_eq!(view_of(2, [0, 0, w.div_ceil(2), h.div_ceil(2)], false).len(), 4 * w.div_ceil(2) * h.div_ceil(2));
        assert_ne!(view_of(1, [2, 3, 20, 9], true), want);
        let vr = serde_json::json!({"width": w, "height": h, "background": [0, 0, 0, 0], "shrink": 2, "region": [0, 0, 99, 1],
            "layers": [{"grid": grid, "image": image, "offset": [0, 0]}]});
        let (f, f_len) = put(vr.to_string().as_bytes());
        assert_eq!(iw_view_draw(f, f_len, iw_alloc(4 * 99), 4 * 99), 1);
        assert!(result()["error"].as_str().unwrap().contains("is not inside"), "{}", result());
        // A frame draw takes the kept field, as before.
        assert_eq!(frame(None), whole);
        let bad = serde_json::json!({"width": w, "height": h, "background": [0, 0, 0, 0],
            "layers": [{"grid": grid, "image": 999, "offset": [0, 0]}]});
        let (f, f_len) = put(bad.to_string().as_bytes());
        assert_eq!(iw_frame_draw(f, f_len, iw_alloc(4 * n), 4 * n), 1);
        assert!(result()["error"].as_str().unwrap().contains("Layer 0 of the frame: there is no picture with handle 999"));
        // The kept field was taken by the draw: the next one is at rest, the picture itself.
        let c = iw_canvas_new(w, h, 0, 0, 0, 0);
        assert_eq!(iw_canvas_draw_solved(c, grid, image, 0.0, 0.0), 0, "{}", result());
        assert_eq!(read(c), rgba);
        // The kept picture reads back; a freed one is an error naming it.
        let back = iw_alloc(4 * n);
        assert_eq!(iw_image_read(image, back, 4 * n), 0);
        assert_eq!(view(back, 4 * n), &rgba[..]);
        iw_image_free(image);
        assert_eq!(iw_canvas_draw_solved(c, grid, image, 0.0, 0.0), 1);
        assert!(result()["error"].as_str().unwrap().contains(&format!("no picture with handle {image}")));
        for canvas in [a, b, c] {
            iw_canvas_free(canvas);
        }
        iw_grid_free(grid);
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
        let links = view(out, 12);
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
        let f = view(field, 2 * n);
        for i in [0, 77, n - 1] {
            assert!((f[i] - 2.0).abs() < 0.05, "dx[{i}] = {}", f[i]);
            assert!((f[n + i] + 1.0).abs() < 0.05, "dy[{i}] = {}", f[n + i]);
        }
        assert_eq!(result()["constrained_nodes"], 1);
        iw_grid_free(h);
    }

    #[test]
    fn a_solve_at_selected_pixels_reads_the_full_solve() {
        // A cut through the layer, a draft of the grid thin plate (sparse: its own
        // upsampling at the pixels) and a triangulation (solved in full, then read): each
        // the full solve's values at the selected pixels.
        let (w, h) = (40, 30);
        let (cuts, cuts_len) = put(b"[[[20.5, 3], [20.5, 26]]]");
        let grid = iw_grid_new(w, h, std::ptr::null(), 0, cuts, cuts_len);
        let n = w * h;
        let pixels: Vec<u32> = (0..n as u32).filter(|p| p % 7 == 0 || (p % w as u32).abs_diff(20) <= 1).collect();
        let (sel, _) = put(&pixels.iter().flat_map(|p| p.to_le_bytes()).collect::<Vec<u8>>());
        assert_eq!(iw_grid_select(grid, sel as *const u32, pixels.len()), 0, "{}", result());
        let features = serde_json::json!([
            {"kind": "point", "rest": [[5, 5]], "pose": [[8, 4]]},
            {"kind": "point", "rest": [[35, 25]], "pose": [[33, 27]]},
            {"kind": "polyline", "rest": [[10, 20], [30, 10]], "pose": [[11, 22], [29, 12]]},
        ]);
        let field = iw_alloc(8 * n) as *mut f32;
        let out = iw_alloc(8 * pixels.len()) as *mut f32;
        for options in [
            serde_json::json!({"method": "tps", "grid_step": 4}),
            serde_json::json!({"method": "triangulation"}),
        ] {
            let req = serde_json::json!({"features": features, "options": options});
            // Each from an empty history: the full solve first, on a fresh grid.
            let full_grid = iw_grid_new(w, h, std::ptr::null(), 0, cuts, cuts_len);
            solve_ok(full_grid, &req, field, "full");
            let (r, r_len) = put(req.to_string().as_bytes());
            assert_eq!(iw_solve_at(grid, r, r_len, out), 0, "{}", result());
            assert_eq!(result()["method"], options["method"]);
            let (f, o) = (view(field, 2 * n), view(out, 2 * pixels.len()));
            for (k, &p) in pixels.iter().enumerate() {
                let p = p as usize;
                assert!((o[2 * k] - f[p]).abs() < 1e-4 && (o[2 * k + 1] - f[n + p]).abs() < 1e-4, "{options}: pixel {p}");
            }
            iw_grid_free(full_grid);
        }
        // Pixels outside the grid are refused, and a grid without a selection says so.
        let (bad, _) = put(&(n as u32).to_le_bytes());
        assert_eq!(iw_grid_select(grid, bad as *const u32, 1), 1);
        assert!(result()["error"].as_str().unwrap().contains("outside"), "{}", result());
        let other = iw_grid_new(w, h, std::ptr::null(), 0, std::ptr::null(), 0);
        let (r, r_len) = put(br#"{"features": [], "options": {"grid_step": 4}}"#);
        assert_eq!(iw_solve_at(other, r, r_len, out), 1);
        assert!(result()["error"].as_str().unwrap().contains("iw_grid_select"), "{}", result());
        iw_grid_free(other);
        iw_grid_free(grid);
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
        let h = iw_grid_new(4, 4, std::ptr::null(), 0, std::ptr::null(), 0);
        let (req, req_len) = put(br#"{"features": [], "options": {"method": "bicubic"}}"#);
        assert_eq!(iw_solve(h, req, req_len, std::ptr::null(), std::ptr::null_mut()), 1);
        assert!(result()["error"].as_str().unwrap().contains("Unknown method \"bicubic\""));
        let (req, req_len) = put(br#"{"features": [], "options": {"scheme": "jacobi"}}"#);
        assert_eq!(iw_solve(h, req, req_len, std::ptr::null(), std::ptr::null_mut()), 1);
        assert!(result()["error"].as_str().unwrap().contains("Unknown solver scheme \"jacobi\""));
        iw_grid_free(h);
        // A freed handle is gone.
        let (req, req_len) = put(br#"{"features": []}"#);
        assert_eq!(iw_solve(h, req, req_len, std::ptr::null(), std::ptr::null_mut()), 1);
        assert!(result()["error"].as_str().unwrap().contains(&format!("no grid with handle {h}")));
    }

    /// Settings of the interpolants other than their defaults (`max_samples` low enough
    /// to thin the drawing's samples).
    const SOLVER: &str = r#"{"beier_neely": {"a": 2.5, "b": 1.5, "p": 0.5}, "tps_exact": {"max_samples": 60}}"#;

    /// A drawing with every kind of feature, as a scene (its second layer driven by
    /// nothing) and as `iw_solve`'s features at time `t` (posed by the scene itself).
    fn every_kind(t: f64) -> (inkwarp_core::scene::Scene, serde_json::Value, serde_json::Value) {
        let features = serde_json::json!([
            {"id": "pin", "kind": "point", "rest": [[3, 3]]},
            {"id": "pull", "kind": "point", "rest": [[40, 30]], "keys": [{"t": 1, "points": [[43, 27]]}]},
            {"id": "bone", "kind": "polyline", "rest": [[6, 20], [14, 24], [22, 20]],
             "keys": [{"t": 1, "points": [[6, 22], [15, 28], [23, 21]]}]},
            {"id": "loop", "kind": "polyline", "closed": true, "rest": [[30, 5], [38, 6], [34, 12]],
             "keys": [{"t": 1, "points": [[31, 6], [39, 8], [34, 14]]}]},
            {"id": "brow", "kind": "spline", "rest": [[8, 8], [16, 5], [24, 8]],
             "keys": [{"t": 1, "points": [[8, 6], [16, 2], [24, 7]]}]},
            {"id": "patch", "kind": "region", "rest": [[8, 28], [16, 28], [16, 36], [8, 36]],
             "keys": [{"t": 1, "points": [[9, 29], [17, 29], [17, 37], [9, 36]]}]},
            {"id": "blob", "kind": "region", "curve": "spline", "rest": [[28, 22], [36, 24], [32, 32]],
             "keys": [{"t": 1, "points": [[27, 21], [37, 24], [31, 33]]}]},
            {"id": "tear", "kind": "cut", "rest": [[25.5, 14], [25.5, 38]]}
        ]);
        let solver: serde_json::Value = serde_json::from_str(SOLVER).unwrap();
        let doc = serde_json::json!({"inkwarp": 1, "width": 48, "height": 40, "solver": solver,
                                     "layers": [{"name": "a"}, {"name": "still", "features": []}],
                                     "features": features});
        let scene = inkwarp_core::scene::Scene::from_json(&doc.to_string(), &mut inkwarp_core::scene::no_files)
            .unwrap();
        let posed: Vec<serde_json::Value> = features
            .as_array()
            .unwrap()
            .iter()
            .enumerate()
            .filter(|(_, f)| f["kind"] != "cut")
            .map(|(i, f)| {
                serde_json::json!({
                    "id": f["id"], "kind": f["kind"], "rest": f["rest"], "pose": scene.pose_at(i, t),
                    "closed": f["kind"] == "region" || f["closed"] == true,
                    "spline_outline": f["curve"] == "spline",
                })
            })
            .collect();
        let cuts = serde_json::json!([features[7]["rest"]]);
        (scene, serde_json::Value::from(posed), cuts)
    }

    #[test]
    fn every_method_gives_the_scene_engines_field() {
        use inkwarp_core::methods::Method;
        use inkwarp_core::scene::SolverOverrides;
        let (scene, features, cuts) = every_kind(0.6);
        let (w, h) = (48, 40);
        let (cuts, cuts_len) = put(cuts.to_string().as_bytes());
        let grid = iw_grid_new(w, h, std::ptr::null(), 0, cuts, cuts_len);
        let out = iw_alloc(8 * w * h) as *mut f32;
        let mut fields = Vec::new();
        let mut options: serde_json::Value = serde_json::from_str(SOLVER).unwrap();
        for method in Method::ALL {
            let expected = scene.layer_field_overridden(0, 0.6, None, &SolverOverrides::method(Some(method))).unwrap().field;
            options["method"] = method.name().into();
            let what = method.to_string();
            let report = solve_ok(grid, &serde_json::json!({"features": features, "options": options}), out, &what);
            if method == Method::TpsExact {
                assert_eq!(report["samples_used"], 60, "{report}");
            }
            // A layer that nothing drives stays put under every method.
            solve_ok(grid, &serde_json::json!({"features": [], "options": options}), out, &what);
            assert!(view(out, 2 * w * h).iter().all(|&v| v == 0.0));
            let still = scene.layer_field_overridden(1, 0.6, None, &SolverOverrides::method(Some(method))).unwrap().field;
            assert!(still.dx.iter().chain(&still.dy).all(|&v| v == 0.0));
            solve_ok(grid, &serde_json::json!({"features": features, "options": options}), out, &what);
            assert_eq!(report["method"], method.name());
            let got = view(out, 2 * w * h);
            let same = got[..w * h] == expected.dx[..] && got[w * h..] == expected.dy[..];
            assert!(same, "{method}: the adapter's field differs from the scene engine's");
            // The methods that know nothing of cuts say so.
            let notes = report["notes"].as_array().unwrap();
            assert_eq!(
                notes.iter().any(|n| n.as_str().unwrap().contains("ignores the continuity matte")),
                method != Method::Tps,
                "{method}: {notes:?}"
            );
            fields.push(got.to_vec());
        }
        // Four different surfaces.
        for i in 0..fields.len() {
            for j in 0..i {
                assert_ne!(fields[i], fields[j], "methods {i} and {j} give the same field");
            }
        }
        iw_grid_free(grid);
    }

    #[test]
    fn a_tps_exact_draft_is_close_to_the_final_field() {
        let (_, features, cuts) = every_kind(0.6);
        let (w, h) = (48, 40);
        let (cuts, cuts_len) = put(cuts.to_string().as_bytes());
        let grid = iw_grid_new(w, h, std::ptr::null(), 0, cuts, cuts_len);
        let field = |step: usize, preview: bool| {
            let out = iw_alloc(8 * w * h) as *mut f32;
            let req = serde_json::json!({"features": features, "spacing_px": 1,
                                         "options": {"method": "tps-exact", "grid_step": step, "preview": preview}});
            let report = solve_ok(grid, &req, out, "tps-exact");
            (view(out, 2 * w * h).to_vec(), report)
        };
        let (exact, _) = field(1, false);
        // grid_step means nothing to tps-exact but in a preview.
        assert_eq!(field(4, false).0, exact);
        let (draft, report) = field(4, true);
        // At most 250 samples fitted, evaluated on every 4th pixel and bilinear between.
        // The drawing moves by up to 4 px; the draft is a preview within a pixel of the
        // final field, and much closer on average.
        assert!(report["samples_used"].as_u64().unwrap() <= 250, "{report}");
        assert!(report["notes"][0].as_str().unwrap().contains("tps-exact ignores the continuity matte"));
        let diff: Vec<f32> = exact.iter().zip(&draft).map(|(a, b)| (a - b).abs()).collect();
        let worst = diff.iter().copied().fold(0.0f32, f32::max);
        let mean = diff.iter().sum::<f32>() / diff.len() as f32;
        assert!(worst < 1.0 && mean < 0.1, "the draft is {worst} px off at worst, {mean} px on average");
        assert!(worst > 0.0, "the draft is a different computation");
        iw_grid_free(grid);
    }

    #[test]
    fn keyframes_and_methods_come_from_the_engine() {
        let (req, len) = put(br#"{"rest": [[0, 0]], "keys": [{"t": 0, "points": [[0, 0]], "interpolation": "linear"}, {"t": 2, "points": [[4, 2]]}], "t": 1}"#);
        assert_eq!(iw_points_at(req, len), 0);
        assert_eq!(result(), serde_json::json!([[2.0, 1.0]]));
        assert_eq!(iw_methods(), 0);
        assert_eq!(
            result(),
            serde_json::json!([
                {"name": "tps", "available": true},
                {"name": "tps-exact", "available": true},
                {"name": "triangulation", "available": true},
                {"name": "beier-neely", "available": true}
            ])
        );
    }
}
