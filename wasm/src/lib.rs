//! riseg-wasm: RISeg in the browser, a thin wasm-bindgen skin over riseg-core and riseg's
//! pure parts (scene reading, the built-in static segmenter and optical flow, the tracker,
//! FindAction, the UOIS metrics, riseg's colours).
//!
//! # Contract (JavaScript)
//!
//! ```js
//! const files = new SceneFiles();
//! files.add("scene_000/scene_camera.json", bytes);   // Uint8Array, one per file
//! const s = Session.open(files, "scene_000");          // throws riseg's message: file, problem
//! for (let t = 0; t < s.frames; t++) {
//!   s.segment(t); if (t > 0) s.flow(t); s.update(t); s.findAction();   // time each call
//!   s.mask();            // Uint16Array: RISeg's mask of frame t, bit-identical to `riseg run`
//! }
//! ```
//!
//! - Pixel data crosses as typed arrays, never JSON: file bytes in (`Uint8Array`, copied
//!   once into wasm memory), and each output out as a typed array of its own (copied once
//!   out of wasm memory, so it stays valid when the memory grows and can be kept per
//!   frame for stepping back).
//! - Frames run in order, one stage per call ([`Session::segment`], [`Session::flow`],
//!   [`Session::update`], [`Session::find_action`]), so the page measures each stage's
//!   milliseconds with `performance.now()`: wasm32-unknown-unknown has no clock of its own.
//! - Every error is a JS exception (`Error`) with the message riseg prints (the file and
//!   the problem for a bad scene); a Rust panic is printed with `console.error` before the
//!   module traps, never a silent empty result.
//! - riseg's (host) types are named in one module, `adapter`; `js` only maps its plain
//!   slices, arrays and messages to JS.
//!
//! # Features
//!
//! - `js`: the JS API above (wasm-bindgen). `web/build.sh` builds with it. Without it the
//!   crate is the adapter alone, whose native unit tests `cargo test --workspace` runs
//!   without compiling wasm-bindgen's proc macros: they turn on features of `syn` that
//!   nothing else in the workspace does, so `cargo run --release` and the tests could not
//!   share one build of every crate with a derive macro (serde, clap, thiserror, ...).

// Without `js` nothing but the adapter's own tests calls it (`cargo clippy --workspace`
// with default features would otherwise call every item dead).
#[cfg_attr(not(feature = "js"), allow(dead_code))]
mod adapter;
#[cfg(feature = "js")]
mod js;

#[cfg(feature = "js")]
pub use js::*;
