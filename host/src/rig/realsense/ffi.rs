//! The librealsense2 C API subset the driver calls, loaded at run time, behind a safe
//! [`Session`]: every pointer stays in this module, frames are copied out before their
//! handles are released, and every handle is released on every path (RAII guards).
//!
//! Declarations follow librealsense2 v2.56.5 (`include/librealsense2/rs.h`,
//! `h/rs_types.h`, `h/rs_context.h`, `h/rs_device.h`, `h/rs_sensor.h`, `h/rs_frame.h`,
//! `h/rs_pipeline.h`, `h/rs_config.h`, `h/rs_processing.h`); every function used exists
//! unchanged since v2.50, the API version passed to `rs2_create_context`
//! ([`API_VERSION`]): librealsense refuses an older runtime with its own clear error.

use core::ffi::{CStr, c_char, c_int, c_uint, c_void};
use std::path::{Path, PathBuf};

use libloading::Library;

/// `RS2_API_VERSION` of v2.50.0 (`rs.h`: major·10000 + minor·100 + patch).
pub(super) const API_VERSION: c_int = 2 * 10000 + 50 * 100;

/// `rs2_stream` (`rs_sensor.h`): `RS2_STREAM_ANY, RS2_STREAM_DEPTH, RS2_STREAM_COLOR, ...`.
const RS2_STREAM_DEPTH: c_int = 1;
const RS2_STREAM_COLOR: c_int = 2;
/// `rs2_format` (`rs_sensor.h`): `RS2_FORMAT_ANY, RS2_FORMAT_Z16, RS2_FORMAT_DISPARITY16,
/// RS2_FORMAT_XYZ32F, RS2_FORMAT_YUYV, RS2_FORMAT_RGB8, ...`.
const RS2_FORMAT_Z16: c_int = 1;
const RS2_FORMAT_RGB8: c_int = 5;
/// `rs2_distortion` (`rs_types.h`): `RS2_DISTORTION_NONE, ..._MODIFIED_BROWN_CONRADY,
/// ..._INVERSE_BROWN_CONRADY, ...`; the others are reported by number.
const RS2_DISTORTION_NAMES: [&str; 6] = [
    "none",
    "modified Brown-Conrady",
    "inverse Brown-Conrady",
    "F-Theta",
    "Brown-Conrady",
    "Kannala-Brandt 4",
];

/// `rs2_intrinsics` (`rs_types.h`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Rs2Intrinsics {
    pub width: c_int,
    pub height: c_int,
    pub ppx: f32,
    pub ppy: f32,
    pub fx: f32,
    pub fy: f32,
    /// `rs2_distortion`.
    pub model: c_int,
    pub coeffs: [f32; 5],
}

impl Rs2Intrinsics {
    /// The distortion model's name.
    pub fn model_name(&self) -> String {
        usize::try_from(self.model)
            .ok()
            .and_then(|i| RS2_DISTORTION_NAMES.get(i))
            .map_or_else(|| format!("model {}", self.model), |s| (*s).to_owned())
    }
}

// Opaque librealsense2 handles.
type Err = c_void;
type Ctx = c_void;
type DevList = c_void;
type Pipe = c_void;
type Conf = c_void;
type Profile = c_void;
type Frame = c_void;
type Block = c_void;
type Queue = c_void;
type StreamProfile = c_void;
type E = *mut *mut Err;

/// The functions, as declared in the headers (module docs).
struct Api {
    get_error_message: unsafe extern "C" fn(*const Err) -> *const c_char,
    get_failed_function: unsafe extern "C" fn(*const Err) -> *const c_char,
    free_error: unsafe extern "C" fn(*mut Err),
    create_context: unsafe extern "C" fn(c_int, E) -> *mut Ctx,
    delete_context: unsafe extern "C" fn(*mut Ctx),
    query_devices: unsafe extern "C" fn(*const Ctx, E) -> *mut DevList,
    get_device_count: unsafe extern "C" fn(*const DevList, E) -> c_int,
    delete_device_list: unsafe extern "C" fn(*mut DevList),
    create_pipeline: unsafe extern "C" fn(*mut Ctx, E) -> *mut Pipe,
    delete_pipeline: unsafe extern "C" fn(*mut Pipe),
    pipeline_stop: unsafe extern "C" fn(*mut Pipe, E),
    pipeline_wait_for_frames: unsafe extern "C" fn(*mut Pipe, c_uint, E) -> *mut Frame,
    pipeline_start_with_config: unsafe extern "C" fn(*mut Pipe, *mut Conf, E) -> *mut Profile,
    delete_pipeline_profile: unsafe extern "C" fn(*mut Profile),
    create_config: unsafe extern "C" fn(E) -> *mut Conf,
    delete_config: unsafe extern "C" fn(*mut Conf),
    config_enable_stream:
        unsafe extern "C" fn(*mut Conf, c_int, c_int, c_int, c_int, c_int, c_int, E),
    release_frame: unsafe extern "C" fn(*mut Frame),
    embedded_frames_count: unsafe extern "C" fn(*mut Frame, E) -> c_int,
    extract_frame: unsafe extern "C" fn(*mut Frame, c_int, E) -> *mut Frame,
    get_frame_data: unsafe extern "C" fn(*const Frame, E) -> *const c_void,
    get_frame_width: unsafe extern "C" fn(*const Frame, E) -> c_int,
    get_frame_height: unsafe extern "C" fn(*const Frame, E) -> c_int,
    get_frame_stride_in_bytes: unsafe extern "C" fn(*const Frame, E) -> c_int,
    depth_frame_get_units: unsafe extern "C" fn(*const Frame, E) -> f32,
    get_frame_stream_profile: unsafe extern "C" fn(*const Frame, E) -> *const StreamProfile,
    get_stream_profile_data: unsafe extern "C" fn(
        *const StreamProfile,
        *mut c_int,
        *mut c_int,
        *mut c_int,
        *mut c_int,
        *mut c_int,
        E,
    ),
    get_video_stream_intrinsics: unsafe extern "C" fn(*const StreamProfile, *mut Rs2Intrinsics, E),
    create_align: unsafe extern "C" fn(c_int, E) -> *mut Block,
    create_spatial_filter_block: unsafe extern "C" fn(E) -> *mut Block,
    create_temporal_filter_block: unsafe extern "C" fn(E) -> *mut Block,
    create_hole_filling_filter_block: unsafe extern "C" fn(E) -> *mut Block,
    delete_processing_block: unsafe extern "C" fn(*mut Block),
    create_frame_queue: unsafe extern "C" fn(c_int, E) -> *mut Queue,
    delete_frame_queue: unsafe extern "C" fn(*mut Queue),
    start_processing_queue: unsafe extern "C" fn(*mut Block, *mut Queue, E),
    process_frame: unsafe extern "C" fn(*mut Block, *mut Frame, E),
    wait_for_frame: unsafe extern "C" fn(*mut Queue, c_uint, E) -> *mut Frame,
    // Last: dropped after every function pointer above is gone.
    _lib: Library,
}

/// Why the library could not be used; [`super::RealSenseError`] words it for the user.
#[derive(Debug)]
pub(super) enum LoadError {
    /// No candidate could be opened: each name tried and why it failed.
    NotFound(Vec<(String, String)>),
    /// The library opened but lacks a function.
    MissingSymbol { path: String, symbol: String },
}

macro_rules! load_api {
    ($lib:expr, $path:expr, { $($field:ident),* $(,)? }) => {{
        let lib = $lib;
        Api {
            $($field: {
                let name = concat!("rs2_", stringify!($field), "\0");
                // SAFETY: the field's type is the C declaration of this symbol in the
                // v2.56.5 headers (module docs); a library exporting the name with another
                // signature is not librealsense2.
                *unsafe { lib.get(name.as_bytes()) }.map_err(|_| LoadError::MissingSymbol {
                    path: $path.to_owned(),
                    symbol: name.trim_end_matches('\0').to_owned(),
                })?
            },)*
            _lib: lib,
        }
    }};
}

impl Api {
    fn open(explicit: Option<&Path>) -> Result<(Self, String), LoadError> {
        let candidates: Vec<PathBuf> = match explicit {
            Some(p) => vec![p.to_owned()],
            None => super::LIBRARY_NAMES.iter().map(PathBuf::from).collect(),
        };
        let mut tried = Vec::new();
        for path in candidates {
            // SAFETY: loading runs the library's initialisers; librealsense2's only set up
            // its own state. The user chose this file (RISEG_REALSENSE_LIB) or it is on
            // the system's library path under librealsense2's name.
            match unsafe { Library::new(&path) } {
                Ok(lib) => {
                    let shown = path.display().to_string();
                    let api = load_api!(lib, shown, {
                        get_error_message, get_failed_function, free_error, create_context,
                        delete_context, query_devices, get_device_count, delete_device_list,
                        create_pipeline, delete_pipeline, pipeline_stop,
                        pipeline_wait_for_frames, pipeline_start_with_config,
                        delete_pipeline_profile, create_config, delete_config,
                        config_enable_stream, release_frame, embedded_frames_count,
                        extract_frame, get_frame_data, get_frame_width, get_frame_height,
                        get_frame_stride_in_bytes, depth_frame_get_units,
                        get_frame_stream_profile, get_stream_profile_data,
                        get_video_stream_intrinsics, create_align,
                        create_spatial_filter_block, create_temporal_filter_block,
                        create_hole_filling_filter_block, delete_processing_block,
                        create_frame_queue, delete_frame_queue, start_processing_queue,
                        process_frame, wait_for_frame,
                    });
                    return Ok((api, shown));
                }
                Err(e) => tried.push((path.display().to_string(), e.to_string())),
            }
        }
        Err(LoadError::NotFound(tried))
    }

    /// Calls `f` with an error slot; a set error becomes `Err("function: message")` and is
    /// freed.
    fn call<T>(&self, f: impl FnOnce(E) -> T) -> Result<T, String> {
        let mut err: *mut Err = core::ptr::null_mut();
        let value = f(&mut err);
        if err.is_null() {
            return Ok(value);
        }
        // SAFETY: `err` was set by librealsense2 and is valid until `free_error`; the
        // strings it returns live as long as the error and are copied before it is freed.
        let text = unsafe {
            let text = |p: *const c_char| {
                if p.is_null() {
                    String::new()
                } else {
                    CStr::from_ptr(p).to_string_lossy().into_owned()
                }
            };
            let msg = format!(
                "{}: {}",
                text((self.get_failed_function)(err)),
                text((self.get_error_message)(err))
            );
            (self.free_error)(err);
            msg
        };
        Err(text)
    }

    /// [`Api::call`] for functions returning a handle: a null handle without an error is
    /// an error too.
    fn handle<T>(&self, what: &str, f: impl FnOnce(E) -> *mut T) -> Result<*mut T, String> {
        let p = self.call(f)?;
        if p.is_null() {
            Err(format!("{what} returned no handle"))
        } else {
            Ok(p)
        }
    }
}

/// A frame (or frameset) handle, released on drop.
struct FrameRef<'a> {
    api: &'a Api,
    ptr: *mut Frame,
}

impl FrameRef<'_> {
    /// Gives the handle away (to `rs2_process_frame`, which takes ownership).
    fn into_raw(self) -> *mut Frame {
        let ptr = self.ptr;
        core::mem::forget(self);
        ptr
    }
}

impl Drop for FrameRef<'_> {
    fn drop(&mut self) {
        // SAFETY: `ptr` is a frame reference this guard owns (not null by construction).
        unsafe { (self.api.release_frame)(self.ptr) }
    }
}

/// What the driver asks of the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct StreamRequest {
    pub width: c_int,
    pub height: c_int,
    pub fps: c_int,
    pub spatial: bool,
    pub temporal: bool,
    pub hole_filling: bool,
}

/// One aligned capture, copied out of librealsense's buffers.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Capture {
    pub width: usize,
    pub height: usize,
    /// Packed RGB, `width·height·3`.
    pub rgb: Vec<u8>,
    /// Depth aligned to colour, raw units, `width·height`.
    pub depth_raw: Vec<u16>,
    /// Metres per raw depth unit.
    pub depth_unit_m: f32,
    /// The colour stream's intrinsics.
    pub intrinsics: Rs2Intrinsics,
}

/// Why a [`Session`] could not start.
#[derive(Debug)]
pub(super) enum StartError {
    Load(LoadError),
    /// The library is there and no device is connected; the library's path.
    NoDevice(String),
    /// librealsense2 refused a call; the library's path and its message.
    Device(String, String),
}

/// A started pipeline with its processing blocks; stopped and freed on drop.
pub(super) struct Session {
    ctx: *mut Ctx,
    pipe: *mut Pipe,
    profile: *mut Profile,
    /// Filters then the align block, each with its output queue, in processing order.
    blocks: Vec<(*mut Block, *mut Queue)>,
    // Last: every handle above is freed before the library is unloaded.
    api: Api,
}

impl core::fmt::Debug for Session {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Session")
            .field("blocks", &self.blocks.len())
            .finish_non_exhaustive()
    }
}

impl Session {
    /// Loads the library, finds a device and starts colour (RGB8) and depth (Z16) at the
    /// requested size and rate; returns the session and the library's path.
    pub fn start(
        library: Option<&Path>,
        req: &StreamRequest,
    ) -> Result<(Self, String), StartError> {
        let (api, path) = Api::open(library).map_err(StartError::Load)?;
        let fail = |e: String| StartError::Device(path.clone(), e);
        // SAFETY: each call below passes handles this function created and has not freed,
        // and out-pointers to live locals; the error slot is handled by `Api::call`.
        let ctx = api
            .handle("rs2_create_context", |e| unsafe {
                (api.create_context)(API_VERSION, e)
            })
            .map_err(fail)?;
        let mut session = Self {
            ctx,
            pipe: core::ptr::null_mut(),
            profile: core::ptr::null_mut(),
            blocks: Vec::new(),
            api,
        };
        let api = &session.api;
        // SAFETY: as above.
        let devices = unsafe {
            let list = api
                .handle("rs2_query_devices", |e| (api.query_devices)(ctx, e))
                .map_err(fail)?;
            let count = api.call(|e| (api.get_device_count)(list, e));
            (api.delete_device_list)(list);
            count.map_err(fail)?
        };
        if devices <= 0 {
            return Err(StartError::NoDevice(path));
        }
        // SAFETY: as above; `conf` is freed on every path after the pipeline starts.
        unsafe {
            session.pipe = api
                .handle("rs2_create_pipeline", |e| (api.create_pipeline)(ctx, e))
                .map_err(fail)?;
            let conf = api
                .handle("rs2_create_config", |e| (api.create_config)(e))
                .map_err(fail)?;
            let started = api
                .call(|e| {
                    let streams = [
                        (RS2_STREAM_COLOR, RS2_FORMAT_RGB8),
                        (RS2_STREAM_DEPTH, RS2_FORMAT_Z16),
                    ];
                    for (stream, format) in streams {
                        (api.config_enable_stream)(
                            conf, stream, -1, req.width, req.height, format, req.fps, e,
                        );
                        if !(*e).is_null() {
                            return core::ptr::null_mut();
                        }
                    }
                    (api.pipeline_start_with_config)(session.pipe, conf, e)
                })
                .and_then(|p| {
                    if p.is_null() {
                        Err("rs2_pipeline_start_with_config returned no profile".into())
                    } else {
                        Ok(p)
                    }
                });
            (api.delete_config)(conf);
            session.profile = started.map_err(fail)?;
        }
        let filters = [
            (
                req.spatial,
                api.create_spatial_filter_block,
                "rs2_create_spatial_filter_block",
            ),
            (
                req.temporal,
                api.create_temporal_filter_block,
                "rs2_create_temporal_filter_block",
            ),
            (
                req.hole_filling,
                api.create_hole_filling_filter_block,
                "rs2_create_hole_filling_filter_block",
            ),
        ];
        let mut blocks = Vec::new();
        for (on, create, name) in filters {
            if on {
                // SAFETY: a constructor with only the error slot.
                blocks.push(api.handle(name, |e| unsafe { create(e) }).map_err(fail)?);
            }
        }
        // SAFETY: as above.
        let align = api
            .handle("rs2_create_align", |e| unsafe {
                (api.create_align)(RS2_STREAM_COLOR, e)
            })
            .map_err(fail)?;
        blocks.push(align);
        for block in blocks {
            // SAFETY: `block` was just created; the queue is started on it once.
            let queue = unsafe {
                api.handle("rs2_create_frame_queue", |e| (api.create_frame_queue)(1, e))
                    .and_then(|q| {
                        api.call(|e| (api.start_processing_queue)(block, q, e))
                            .map(|()| q)
                            .inspect_err(|_| (api.delete_frame_queue)(q))
                    })
            };
            match queue {
                Ok(q) => session.blocks.push((block, q)),
                Err(e) => {
                    // SAFETY: not yet owned by the session.
                    unsafe { (api.delete_processing_block)(block) };
                    return Err(fail(e));
                }
            }
        }
        Ok((session, path))
    }

    /// Waits for the next frameset and drops it (warm-up, settling).
    pub fn skip(&mut self, timeout_ms: u32) -> Result<(), String> {
        self.next_frameset(timeout_ms).map(drop)
    }

    fn next_frameset(&self, timeout_ms: u32) -> Result<FrameRef<'_>, String> {
        let api = &self.api;
        // SAFETY: `pipe` is a started pipeline owned by this session.
        let ptr = api.handle("rs2_pipeline_wait_for_frames", |e| unsafe {
            (api.pipeline_wait_for_frames)(self.pipe, timeout_ms, e)
        })?;
        Ok(FrameRef { api, ptr })
    }

    /// The next frameset, filtered and aligned to colour, copied out.
    pub fn capture(&mut self, timeout_ms: u32) -> Result<Capture, String> {
        let api = &self.api;
        let mut frames = self.next_frameset(timeout_ms)?;
        for &(block, queue) in &self.blocks {
            let raw = frames.into_raw();
            // SAFETY: `rs2_process_frame` takes ownership of `raw` (rs_processing.h);
            // the result comes out of the block's own queue as a new reference.
            let out = unsafe {
                api.call(|e| (api.process_frame)(block, raw, e))?;
                api.handle("rs2_wait_for_frame", |e| {
                    (api.wait_for_frame)(queue, timeout_ms, e)
                })?
            };
            frames = FrameRef { api, ptr: out };
        }
        let mut colour = None;
        let mut depth = None;
        // SAFETY: `frames` is a live frameset; extracted frames are new references,
        // released by their guards; data pointers are read within the frame's size and
        // stride before the guard is dropped.
        unsafe {
            let n = api.call(|e| (api.embedded_frames_count)(frames.ptr, e))?;
            for i in 0..n {
                let f = FrameRef {
                    api,
                    ptr: api.handle("rs2_extract_frame", |e| {
                        (api.extract_frame)(frames.ptr, i, e)
                    })?,
                };
                let profile = api.call(|e| (api.get_frame_stream_profile)(f.ptr, e))?;
                let (mut stream, mut format, mut index, mut uid, mut fps) = (0, 0, 0, 0, 0);
                api.call(|e| {
                    (api.get_stream_profile_data)(
                        profile,
                        &mut stream,
                        &mut format,
                        &mut index,
                        &mut uid,
                        &mut fps,
                        e,
                    );
                })?;
                let w = api.call(|e| (api.get_frame_width)(f.ptr, e))?;
                let h = api.call(|e| (api.get_frame_height)(f.ptr, e))?;
                let stride = api.call(|e| (api.get_frame_stride_in_bytes)(f.ptr, e))?;
                let data = api.call(|e| (api.get_frame_data)(f.ptr, e))?.cast::<u8>();
                let (Ok(w), Ok(h), Ok(stride)) = (
                    usize::try_from(w),
                    usize::try_from(h),
                    usize::try_from(stride),
                ) else {
                    return Err(format!(
                        "frame {i} has a negative size {w}x{h}, stride {stride}"
                    ));
                };
                let row_bytes = match (stream, format) {
                    (RS2_STREAM_COLOR, RS2_FORMAT_RGB8) => w * 3,
                    (RS2_STREAM_DEPTH, RS2_FORMAT_Z16) => w * 2,
                    _ => continue,
                };
                if data.is_null() || stride < row_bytes {
                    return Err(format!(
                        "frame of stream {stream} has no data or a stride of {stride} bytes for rows of {row_bytes}"
                    ));
                }
                let mut bytes = Vec::with_capacity(row_bytes * h);
                for y in 0..h {
                    bytes.extend_from_slice(core::slice::from_raw_parts(
                        data.add(y * stride),
                        row_bytes,
                    ));
                }
                if stream == RS2_STREAM_COLOR {
                    let mut intr = Rs2Intrinsics::default();
                    api.call(|e| (api.get_video_stream_intrinsics)(profile, &mut intr, e))?;
                    colour = Some((w, h, bytes, intr));
                } else {
                    let unit = api.call(|e| (api.depth_frame_get_units)(f.ptr, e))?;
                    let raw = bytes
                        .chunks_exact(2)
                        .map(|b| u16::from_ne_bytes([b[0], b[1]]))
                        .collect();
                    depth = Some((w, h, raw, unit));
                }
            }
        }
        let (Some((width, height, rgb, intrinsics)), Some((dw, dh, depth_raw, depth_unit_m))) =
            (colour, depth)
        else {
            return Err("the frameset lacks an RGB8 colour or a Z16 depth frame".into());
        };
        if (dw, dh) != (width, height) {
            return Err(format!(
                "aligned depth is {dw}x{dh}, colour {width}x{height}: not aligned to colour"
            ));
        }
        Ok(Capture {
            width,
            height,
            rgb,
            depth_raw,
            depth_unit_m,
            intrinsics,
        })
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        let api = &self.api;
        // SAFETY: every handle was created by this session and is freed once, in reverse
        // order of creation; null handles (a failed start) are skipped.
        unsafe {
            for &(block, queue) in self.blocks.iter().rev() {
                (api.delete_processing_block)(block);
                (api.delete_frame_queue)(queue);
            }
            if !self.profile.is_null() {
                if let Err(e) = api.call(|e| (api.pipeline_stop)(self.pipe, e)) {
                    log::warn!("RealSense: stopping the pipeline: {e}");
                }
                (api.delete_pipeline_profile)(self.profile);
            }
            if !self.pipe.is_null() {
                (api.delete_pipeline)(self.pipe);
            }
            (api.delete_context)(self.ctx);
        }
    }
}
