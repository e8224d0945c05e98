//! The Embree backend: voxels are the primitives of one Embree 3 user
//! geometry, either grouped into bricks ([`Geometry::Bricks`], the default;
//! see `bricks.rs`) or one axis-aligned box each ([`Geometry::Boxes`]);
//! rays are traced in packets by the C shim in `ffi/`.
//!
//! This is the only module with `unsafe` code. Invariants it keeps:
//! - the device outlives the scene, and the primitive data the geometry's
//!   callbacks read outlives the scene (released first in `Drop`);
//! - the scene is committed once in `new` and never modified afterwards, so
//!   concurrent `rtcIntersect*` calls from many threads are allowed (Embree
//!   documents traversal of a committed scene as thread-safe);
//! - every Embree call is followed by an error check; nothing panics across
//!   the FFI boundary (the callbacks are C).

use std::ffi::CStr;
use std::sync::atomic::{AtomicI64, Ordering};

use super::bricks::{BrickEdge, Bricks};
use super::{Hit, RayCaster};
use crate::geometry::Ray;
use crate::map::Cell;

mod sys {
    #![allow(
        non_upper_case_globals,
        non_camel_case_types,
        non_snake_case,
        dead_code,
        unsafe_op_in_unsafe_fn,
        clippy::all
    )]
    include!(concat!(env!("OUT_DIR"), "/embree_bindings.rs"));
}

// `Ray` and `Hit` are passed to C as `OmclRay` and `OmclHit`: same fields,
// same order, all repr(C).
const _: () = {
    assert!(std::mem::size_of::<Ray>() == std::mem::size_of::<sys::OmclRay>());
    assert!(std::mem::align_of::<Ray>() == std::mem::align_of::<sys::OmclRay>());
    assert!(std::mem::offset_of!(Ray, dir) == std::mem::offset_of!(sys::OmclRay, dir));
    assert!(std::mem::offset_of!(Ray, t_min) == std::mem::offset_of!(sys::OmclRay, tnear));
    assert!(std::mem::offset_of!(Ray, t_max) == std::mem::offset_of!(sys::OmclRay, tfar));
    assert!(std::mem::size_of::<Hit>() == std::mem::size_of::<sys::OmclHit>());
    assert!(std::mem::align_of::<Hit>() == std::mem::align_of::<sys::OmclHit>());
    assert!(std::mem::offset_of!(Hit, leaf) == std::mem::offset_of!(sys::OmclHit, leaf));
    assert!(std::mem::offset_of!(Hit, t) == std::mem::offset_of!(sys::OmclHit, t));
    assert!(Hit::MISS == sys::OMCL_NO_HIT);
};

/// An error reported by Embree.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum EmbreeError {
    #[error("Embree {call} failed: {code} ({message})")]
    Api {
        call: &'static str,
        code: String,
        message: String,
    },
    #[error("{0} voxels exceed the 2^32 - 2 primitives of one Embree geometry")]
    TooManyVoxels(usize),
    #[error("resolution must be positive and finite, got {0}")]
    BadResolution(f32),
}

/// How many consecutive rays form one packet.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Packet {
    /// `rtcIntersect1`, one ray at a time.
    Single,
    /// `rtcIntersect4`.
    Four,
    /// `rtcIntersect8` (the default: measured fastest for camera images,
    /// 10 to 15 % ahead of 16-wide packets with either geometry, and for
    /// the filter's particle-major rays with bricks).
    #[default]
    Eight,
    /// `rtcIntersect16`.
    Sixteen,
    /// Ray streams (`rtcIntersect1M`): Embree regroups the rays itself.
    Stream,
}

impl Packet {
    fn width(self) -> u32 {
        match self {
            Packet::Single => 1,
            Packet::Four => 4,
            Packet::Eight => 8,
            Packet::Sixteen => 16,
            Packet::Stream => 0,
        }
    }
}

/// Embree BVH build quality: faster builds or faster traversal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BuildQuality {
    /// Morton-code builder: fastest build, slowest traversal.
    Low,
    /// Binned SAH builder (the default).
    #[default]
    Medium,
    /// SAH with spatial splits: slowest build.
    High,
}

/// What one Embree primitive is.
///
/// Measured on the 1 M-voxel rooms map at 5 cm (rays per CPU-second,
/// `OMCL_BENCH_GEOMETRIES=3 cargo bench --bench raycast`, see the README):
/// bricks of edge 4 trace camera images 10 to 20 % faster than boxes and
/// the filter's rays (particle-major, 8-wide packets) 2.4 times faster than
/// boxes in that order and 20 to 30 % faster than boxes' best order (single
/// rays, pixel-major); edge 2 is slower than 4 on everything; edge 8 is
/// 10 to 15 % slower than 4 on images and up to 5 % faster on the filter's
/// rays. The BVH shrinks from 92 B/voxel (boxes) to 22, 7 and 1.3 B/voxel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Geometry {
    /// One box per voxel.
    Boxes,
    /// One primitive per non-empty brick of `edge^3` voxels, bounded by the
    /// tight box of its occupied voxels; its callback walks the brick's
    /// cells (the default, with edge 4).
    Bricks(BrickEdge),
}

impl Default for Geometry {
    fn default() -> Self {
        Geometry::Bricks(BrickEdge::default())
    }
}

/// Options of the Embree scene build.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BuildOptions {
    /// What one Embree primitive is.
    pub geometry: Geometry,
    /// BVH build quality.
    pub quality: BuildQuality,
    /// Embree's robust (conservative) traversal, which never misses a box
    /// at a shared face through rounding; slightly slower.
    pub robust: bool,
    /// Bricks in 8-wide packets test all eight rays at once with AVX2 where
    /// the CPU has it (and POPCNT); the rest of the shim is baseline
    /// x86-64. The answers are the same to the bit either way (tested).
    pub wide_simd: bool,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            geometry: Geometry::default(),
            quality: BuildQuality::Medium,
            robust: true,
            wide_simd: true,
        }
    }
}

fn code_name(code: sys::RTCError) -> &'static str {
    match code {
        sys::RTCError::RTC_ERROR_NONE => "no error",
        sys::RTCError::RTC_ERROR_UNKNOWN => "unknown error",
        sys::RTCError::RTC_ERROR_INVALID_ARGUMENT => "invalid argument",
        sys::RTCError::RTC_ERROR_INVALID_OPERATION => "invalid operation",
        sys::RTCError::RTC_ERROR_OUT_OF_MEMORY => "out of memory",
        sys::RTCError::RTC_ERROR_UNSUPPORTED_CPU => "unsupported CPU",
        sys::RTCError::RTC_ERROR_CANCELLED => "cancelled",
    }
}

/// Forgets errors recorded on this thread before a sequence of calls, so
/// that a stale one cannot surface later under another call's name.
fn clear_errors(device: sys::RTCDevice) {
    // SAFETY: a null buffer is allowed (the shim only resets its state);
    // `rtcGetDeviceError` accepts any device handle and null.
    unsafe {
        sys::omcl_take_error(std::ptr::null_mut(), 0);
        sys::rtcGetDeviceError(device);
    }
}

/// Returns the error the device recorded on this thread since the last check.
fn check(device: sys::RTCDevice, call: &'static str) -> Result<(), EmbreeError> {
    let mut buf = [0 as std::os::raw::c_char; 256];
    // SAFETY: `buf` is a writable buffer of the length we pass; the shim
    // NUL-terminates within it. `rtcGetDeviceError` accepts any device
    // handle returned by rtcNewDevice, and null for creation errors.
    let (shim_code, dev_code) = unsafe {
        (
            sys::omcl_take_error(buf.as_mut_ptr(), buf.len()),
            sys::rtcGetDeviceError(device),
        )
    };
    let code = if dev_code != sys::RTCError::RTC_ERROR_NONE {
        dev_code
    } else if shim_code != 0 {
        // The shim stores the enum's integer value; map it back.
        match shim_code {
            1 => sys::RTCError::RTC_ERROR_UNKNOWN,
            2 => sys::RTCError::RTC_ERROR_INVALID_ARGUMENT,
            3 => sys::RTCError::RTC_ERROR_INVALID_OPERATION,
            4 => sys::RTCError::RTC_ERROR_OUT_OF_MEMORY,
            5 => sys::RTCError::RTC_ERROR_UNSUPPORTED_CPU,
            _ => sys::RTCError::RTC_ERROR_CANCELLED,
        }
    } else {
        return Ok(());
    };
    // SAFETY: the buffer is NUL-terminated by the shim (zeroed otherwise).
    let message = unsafe { CStr::from_ptr(buf.as_ptr()) }
        .to_string_lossy()
        .into_owned();
    Err(EmbreeError::Api {
        call,
        code: code_name(code).to_string(),
        message,
    })
}

struct Device(sys::RTCDevice);

/// A geometry handle released on every path, the error paths of `new`
/// included.
struct GeometryHandle(sys::RTCGeometry);

impl Drop for GeometryHandle {
    fn drop(&mut self) {
        // SAFETY: the handle came from rtcNewGeometry and is released once
        // (a scene it was attached to holds its own reference).
        unsafe { sys::rtcReleaseGeometry(self.0) }
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: the handle came from rtcNewDevice and is released once.
        unsafe { sys::rtcReleaseDevice(self.0) }
    }
}

/// The data the geometry's callbacks read through raw pointers: the
/// descriptors are boxed so their addresses stay fixed, and the arrays they
/// point into are never resized; kept until the scene is released.
enum Prims {
    Boxes {
        desc: Box<sys::OmclBoxes>,
        lower: Vec<f32>,
    },
    Bricks {
        desc: Box<sys::OmclBricks>,
        bricks: Bricks,
    },
}

impl Prims {
    fn new(resolution: f32, cells: &[Cell], geometry: Geometry, wide_simd: bool) -> Self {
        match geometry {
            Geometry::Boxes => {
                let lower: Vec<f32> = cells
                    .iter()
                    .flat_map(|c| c.map(|v| v as f32 * resolution))
                    .collect();
                let desc = Box::new(sys::OmclBoxes {
                    lower: lower.as_ptr(),
                    count: cells.len() as u32,
                    size: resolution,
                });
                Prims::Boxes { desc, lower }
            }
            Geometry::Bricks(edge) => {
                let bricks = Bricks::new(cells, edge);
                let desc = Box::new(sys::OmclBricks {
                    data: bricks.data.as_ptr(),
                    count: bricks.count as u32,
                    edge: edge.cells(),
                    size: resolution,
                    inv_size: 1.0 / resolution,
                    wide: wide_simd as u32,
                });
                Prims::Bricks { desc, bricks }
            }
        }
    }

    fn count(&self) -> usize {
        match self {
            Prims::Boxes { desc, .. } => desc.count as usize,
            Prims::Bricks { bricks, .. } => bricks.count,
        }
    }

    fn bytes(&self) -> usize {
        match self {
            Prims::Boxes { lower, .. } => lower.len() * std::mem::size_of::<f32>(),
            Prims::Bricks { bricks, .. } => bricks.bytes(),
        }
    }
}

/// The Embree ray caster.
pub struct EmbreeCaster {
    scene: sys::RTCScene,
    prims: Prims,
    geometry: Geometry,
    resolution: f32,
    len: usize,
    packet: Packet,
    wide_simd: bool,
    device: Device,
    // Bytes Embree allocated, updated by the device's memory monitor; boxed
    // so its address is fixed, and dropped after the device.
    embree_bytes: Box<AtomicI64>,
    // The first error Embree raised while tracing through the infallible
    // `RayCaster` interface, kept for `take_error`.
    trace_error: std::sync::Mutex<Option<EmbreeError>>,
    // Tests only: the next cast (on whichever thread) reports an error.
    inject_error: std::sync::atomic::AtomicBool,
}

// SAFETY: the scene is committed in `new` and never modified afterwards
// (there is no `&mut self` method that touches it), and Embree allows
// concurrent traversal of a committed scene from any thread; the box data
// the callbacks read is immutable for the caster's lifetime.
unsafe impl Send for EmbreeCaster {}
// SAFETY: as for Send: shared access only ever traces rays.
unsafe impl Sync for EmbreeCaster {}

impl std::fmt::Debug for EmbreeCaster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("EmbreeCaster")
            .field("voxels", &self.len)
            .field("resolution", &self.resolution)
            .field("geometry", &self.geometry)
            .field("packet", &self.packet)
            .finish()
    }
}

impl EmbreeCaster {
    /// Builds the scene of voxels of edge `resolution` (metres) at `cells`
    /// (grid frame); hit `leaf` values index `cells`. Default build options.
    pub fn new(resolution: f32, cells: &[Cell]) -> Result<Self, EmbreeError> {
        Self::with_options(resolution, cells, BuildOptions::default())
    }

    /// As [`EmbreeCaster::new`], with explicit build options.
    pub fn with_options(
        resolution: f32,
        cells: &[Cell],
        options: BuildOptions,
    ) -> Result<Self, EmbreeError> {
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(EmbreeError::BadResolution(resolution));
        }
        if cells.len() >= u32::MAX as usize - 1 {
            return Err(EmbreeError::TooManyVoxels(cells.len()));
        }
        // Declared before the device, so that on every early return below
        // the device (whose release reports freed bytes to the monitor) is
        // dropped first and the counter after it.
        let embree_bytes = Box::new(AtomicI64::new(0));
        clear_errors(std::ptr::null_mut());
        // SAFETY: a null config string selects Embree's defaults.
        let raw = unsafe { sys::rtcNewDevice(std::ptr::null()) };
        check(std::ptr::null_mut(), "rtcNewDevice")?;
        if raw.is_null() {
            return Err(EmbreeError::Api {
                call: "rtcNewDevice",
                code: "null device".into(),
                message: String::new(),
            });
        }
        let device = Device(raw);
        // SAFETY: valid device; the error handler only writes thread-local
        // storage. The memory monitor adds atomically into `embree_bytes`,
        // an AtomicI64 (same layout as int64_t) at a fixed heap address that
        // the caster drops after the device.
        unsafe {
            sys::omcl_install_error_handler(device.0);
            sys::omcl_install_memory_monitor(device.0, embree_bytes.as_ptr());
        }
        let prims = Prims::new(resolution, cells, options.geometry, options.wide_simd);
        // SAFETY: valid device.
        let scene = unsafe { sys::rtcNewScene(device.0) };
        check(device.0, "rtcNewScene")?;
        let mut caster = EmbreeCaster {
            scene,
            prims,
            geometry: options.geometry,
            resolution,
            len: cells.len(),
            packet: Packet::default(),
            wide_simd: false,
            device,
            embree_bytes,
            trace_error: std::sync::Mutex::new(None),
            inject_error: std::sync::atomic::AtomicBool::new(false),
        };
        let d = caster.device.0;
        // SAFETY: `scene` is a fresh scene of `d`. The geometry's user data
        // points at the descriptor in `caster.prims`, which lives (boxed, at
        // a fixed address, with the arrays it points into unmoved inside
        // their Vecs' heap buffers) until Drop releases the scene. Each call
        // is checked before the next.
        unsafe {
            // RTC_SCENE_FLAG_COMPACT measured slower on bricks (6 % for
            // camera images, 15 % for MCL rays) for 3 B/voxel less.
            let flags = if options.robust {
                sys::RTCSceneFlags::RTC_SCENE_FLAG_ROBUST
            } else {
                sys::RTCSceneFlags::RTC_SCENE_FLAG_NONE
            };
            sys::rtcSetSceneFlags(scene, flags);
            let quality = match options.quality {
                BuildQuality::Low => sys::RTCBuildQuality::RTC_BUILD_QUALITY_LOW,
                BuildQuality::Medium => sys::RTCBuildQuality::RTC_BUILD_QUALITY_MEDIUM,
                BuildQuality::High => sys::RTCBuildQuality::RTC_BUILD_QUALITY_HIGH,
            };
            sys::rtcSetSceneBuildQuality(scene, quality);
            check(d, "rtcSetSceneFlags")?;
            if caster.prims.count() > 0 {
                let handle = GeometryHandle(sys::rtcNewGeometry(
                    d,
                    sys::RTCGeometryType::RTC_GEOMETRY_TYPE_USER,
                ));
                check(d, "rtcNewGeometry")?;
                let geom = handle.0;
                match &caster.prims {
                    Prims::Boxes { desc, .. } => sys::omcl_set_box_callbacks(geom, &**desc),
                    Prims::Bricks { desc, .. } => {
                        // Cannot fail (-1): the edge comes from a BrickEdge.
                        // 1: the AVX2 callbacks were chosen.
                        caster.wide_simd = sys::omcl_set_brick_callbacks(geom, &**desc) == 1;
                    }
                }
                check(d, "rtcSetGeometryUser*")?;
                sys::rtcCommitGeometry(geom);
                check(d, "rtcCommitGeometry")?;
                sys::rtcAttachGeometry(scene, geom);
                check(d, "rtcAttachGeometry")?;
                drop(handle);
            }
            sys::rtcCommitScene(scene);
            check(d, "rtcCommitScene")?;
        }
        Ok(caster)
    }

    /// Whether the brick callbacks take their AVX2 path for 8-wide packets
    /// ([`BuildOptions::wide_simd`] and a CPU with AVX2 and POPCNT).
    pub fn wide_simd(&self) -> bool {
        self.wide_simd
    }

    /// Chooses the packet width used by [`RayCaster::cast`].
    pub fn with_packet(mut self, packet: Packet) -> Self {
        self.packet = packet;
        self
    }

    /// Bytes of the primitive data handed to Embree: the box array, or the
    /// brick records and their voxel-index table (the BVH itself is
    /// Embree's and not counted here).
    pub fn box_bytes(&self) -> usize {
        self.prims.bytes()
    }

    /// Number of Embree primitives (voxels for boxes, non-empty bricks).
    pub fn primitives(&self) -> usize {
        self.prims.count()
    }

    /// What one Embree primitive is.
    pub fn geometry(&self) -> Geometry {
        self.geometry
    }

    /// Bytes Embree holds for this caster's scene (BVH and bookkeeping), as
    /// reported by its memory monitor.
    pub fn embree_bytes(&self) -> usize {
        self.embree_bytes.load(Ordering::Relaxed).max(0) as usize
    }

    /// Traces rays on the calling thread; the C side writes the hits in
    /// place, brick slots already mapped to voxel indices. An error Embree
    /// raises during the call is returned (the hits are then all misses).
    /// Panics if the slices differ in length.
    pub fn try_cast_serial(&self, rays: &[Ray], hits: &mut [Hit]) -> Result<(), EmbreeError> {
        assert_eq!(rays.len(), hits.len(), "one hit slot per ray");
        let (inv_size, slots): (f32, &[u32]) = match &self.prims {
            Prims::Boxes { .. } => (0.0, &[]),
            Prims::Bricks { desc, bricks } => (desc.inv_size, &bricks.leaves),
        };
        let slots_ptr = if slots.is_empty() {
            std::ptr::null()
        } else {
            slots.as_ptr()
        };
        // SAFETY: `Ray`/`OmclRay` and `Hit`/`OmclHit` have the same layouts
        // (checked at compile time above); `hits` has room for `rays.len()`
        // hits; `slots` is read only within its `slots.len()` entries; the
        // scene is committed and shared read-only.
        if self.inject_error.load(Ordering::Relaxed)
            && self.inject_error.swap(false, Ordering::SeqCst)
        {
            // SAFETY: sets a thread-local flag in the shim, read by the
            // omcl_trace call below on this thread.
            unsafe { sys::omcl_inject_trace_error() }
        }
        let code = unsafe {
            sys::omcl_trace(
                self.scene,
                rays.as_ptr().cast::<sys::OmclRay>(),
                hits.as_mut_ptr().cast::<sys::OmclHit>(),
                rays.len(),
                self.packet.width(),
                inv_size,
                slots_ptr,
                slots.len(),
                self.wide_simd as i32,
            )
        };
        if code == 0 {
            return Ok(());
        }
        hits.fill(Hit::miss());
        // The shim kept the code and message on this thread; `check` takes
        // both (and the device's own record).
        check(self.device.0, "rtcIntersect").and(Err(EmbreeError::Api {
            call: "rtcIntersect",
            code: format!("error code {code}"),
            message: String::new(),
        }))
    }
}

impl RayCaster for EmbreeCaster {
    fn cast_serial(&self, rays: &[Ray], hits: &mut [Hit]) {
        if let Err(e) = self.try_cast_serial(rays, hits) {
            let mut slot = self
                .trace_error
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner());
            slot.get_or_insert(e);
        }
    }

    fn take_error(&self) -> Option<String> {
        self.trace_error
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
            .take()
            .map(|e| e.to_string())
    }

    fn len(&self) -> usize {
        self.len
    }
}

impl EmbreeCaster {
    /// Tests only: the next cast of this caster (on whichever thread)
    /// reports an error the way Embree's error callback does, to exercise
    /// the error path.
    #[doc(hidden)]
    pub fn inject_trace_error_for_test(&self) {
        self.inject_error.store(true, Ordering::SeqCst);
    }

    /// Tests only: makes Embree raise a real error on this caster's device
    /// and returns what [`check`] reports for it.
    #[doc(hidden)]
    pub fn raise_real_error_for_test(&self) -> Result<(), EmbreeError> {
        clear_errors(self.device.0);
        // SAFETY: a valid device; the shim releases anything it creates.
        let failed = unsafe { sys::omcl_raise_real_error(self.device.0) };
        let reported = check(self.device.0, "rtcNewGeometry");
        if failed == 1 && reported.is_ok() {
            return Err(EmbreeError::Api {
                call: "rtcNewGeometry",
                code: "not reported".into(),
                message: "Embree failed the call but no error reached the callback".into(),
            });
        }
        reported
    }
}

/// The calling thread's MXCSR (SSE control and status): tests check that a
/// cast leaves the float mode as it found it.
pub fn thread_float_mode() -> u32 {
    // SAFETY: reads a register of the calling thread; no memory is touched.
    unsafe { sys::omcl_get_csr() }
}

/// Packets traced so far (in this process) whose `valid` mask was not
/// aligned like the packet, as Embree requires; zero unless the shim is
/// broken.
pub fn misaligned_masks() -> u64 {
    // SAFETY: an atomic load of a counter in the shim.
    unsafe { sys::omcl_misaligned_masks() as u64 }
}

impl Drop for EmbreeCaster {
    fn drop(&mut self) {
        // SAFETY: the scene handle came from rtcNewScene and is released
        // once, before the primitive data and the device (dropped after this).
        unsafe { sys::rtcReleaseScene(self.scene) }
    }
}
