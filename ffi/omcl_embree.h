/* The C side of omcl's Embree interop.
 *
 * bindgen reads this header: it pulls in Embree 3's public API (`rtc*`) and
 * declares the small shim below, compiled from omcl_embree.c by `cc`.
 * Voxels are axis-aligned cubes of edge `size` in the map's grid frame
 * (world minus map origin, metres, float): either one user primitive each
 * (OmclBoxes) or grouped into bricks (OmclBricks).
 */
#ifndef OMCL_EMBREE_H
#define OMCL_EMBREE_H

#include <embree3/rtcore.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The boxes of one user geometry. Owned by Rust; must outlive the geometry. */
typedef struct OmclBoxes {
  const float *lower; /* 3 * count floats: x0 y0 z0 x1 y1 z1 ... */
  uint32_t count;
  float size; /* edge length of every box */
} OmclBoxes;

/* Voxels grouped into bricks of edge x edge x edge cells (edge 2, 4 or 8),
 * one user primitive per non-empty brick. Each brick is a record of
 * omcl_brick_words(edge) 64-bit words (built on the Rust side, read with
 * shifts so the layout does not depend on byte order):
 *   word 0: base cell x (low 32 bits, int32), base cell y (high 32 bits);
 *   word 1: base cell z (low), index into `leaves` of its first voxel (high);
 *   word 2: tight bounds of the occupied cells inside the brick, one byte
 *           each: lo x, lo y, lo z, hi x, hi y, hi z (inclusive);
 *   then the occupancy mask, bit x + edge * (y + edge * z) of the brick's
 *   cells (one word for edge 2 and 4, eight for edge 8: word z);
 *   edge 8 only: one more pair of words holding eight 16-bit counts, the
 *   occupied cells in mask words before word z (word 11 for z < 4, 12 after).
 * The leaf slot of an occupied cell is first + rank, rank = the number of
 * occupied cells with a smaller bit index; the caller keeps the table from
 * slots to voxel indices. Owned by Rust; must outlive the geometry. */
typedef struct OmclBricks {
  const uint64_t *data; /* count records */
  uint32_t count;
  uint32_t edge; /* 2, 4 or 8 */
  float size;     /* voxel edge length */
  float inv_size; /* 1 / size: the callbacks work in cell units */
  uint32_t wide;  /* nonzero: 8-wide packets take an AVX2 path where the CPU
                     has AVX2 (same answers as the baseline path) */
} OmclBricks;

/* 64-bit words of one brick record: 4 for edge 2 and 4, 13 for edge 8. */
#define OMCL_BRICK_WORDS_SMALL 4
#define OMCL_BRICK_WORDS_8 13

/* Registers the brick callbacks on `geom` (an RTC_GEOMETRY_TYPE_USER
 * geometry) with `bricks` as user data. Returns 0, 1 when the AVX2
 * callbacks were chosen (bricks->wide and a CPU with AVX2 and POPCNT), or
 * -1 for an edge other than 2, 4 or 8 (nothing registered). Hits report the leaf slot of the
 * hit cell as primID. */
int omcl_set_brick_callbacks(RTCGeometry geom, const OmclBricks *bricks);

/* One ray in, one hit out (array-of-structs on the Rust side). */
typedef struct OmclRay {
  float org[3];
  float dir[3];
  float tnear;
  float tfar;
} OmclRay;

/* The layout of the Rust side's Hit, written in place. */
typedef struct OmclHit {
  uint32_t leaf; /* voxel index, or OMCL_NO_HIT */
  float t;       /* distance along dir (in units of |dir|); INFINITY on a miss */
} OmclHit;

#define OMCL_NO_HIT 0xFFFFFFFFu

/* Registers the bounds, intersect and occluded callbacks of box geometry on
 * `geom` (an RTC_GEOMETRY_TYPE_USER geometry) with `boxes` as user data. */
void omcl_set_box_callbacks(RTCGeometry geom, const OmclBoxes *boxes);

/* Installs an error callback that records the last error of `device`
 * (code and message) for this thread; read it with omcl_take_error. */
void omcl_install_error_handler(RTCDevice device);

/* Returns the last recorded error code (RTC_ERROR_NONE if none) and copies
 * its message into buf (NUL-terminated, truncated to len); clears it. */
int omcl_take_error(char *buf, size_t len);

/* Counts the bytes Embree allocates for `device` (BVH and scene data) into
 * *counter with atomic adds; the counter must outlive the device. */
void omcl_install_memory_monitor(RTCDevice device, int64_t *counter);

/* Sets flush-to-zero and denormals-are-zero on the calling thread. */
void omcl_set_ftz_daz(void);

/* Traces n rays in packets of `packet` (1, 4, 8 or 16) consecutive rays, or
 * as Embree ray streams for packet 0; sets FTZ/DAZ on the calling thread
 * first. For a scene of bricks, inv_size is 1 / voxel size (the rays' cell
 * form is computed once per ray and handed to the callbacks) and slots maps
 * a hit's leaf slot (primID) to its voxel index (n_slots entries; a slot
 * beyond them is a miss); for boxes inv_size is 0 and slots NULL (primID is
 * the voxel index). With `wide` nonzero (bricks whose callbacks took the
 * AVX2 path), 8-wide packets are also assembled with AVX2.
 * Flush-to-zero / denormals-are-zero hold during the call only (the caller's
 * MXCSR is restored). Returns the RTCError code of the first error Embree
 * raised on this thread during the call (0: none; the message is then
 * available from omcl_take_error). */
int omcl_trace(RTCScene scene, const OmclRay *rays, OmclHit *hits, size_t n,
               unsigned packet, float inv_size, const uint32_t *slots,
               size_t n_slots, int wide);

/* The calling thread's MXCSR (for tests of the float mode after a cast). */
unsigned int omcl_get_csr(void);

/* Tests only: the next omcl_trace on this thread reports an error through
 * the error callback, as Embree does for errors raised while tracing. */
void omcl_inject_trace_error(void);

/* Tests only: makes Embree itself raise an error on `device` (an invalid
 * geometry type); returns 1 when the call failed as intended. */
int omcl_raise_real_error(RTCDevice device);

/* Packets traced so far whose valid mask was not aligned like the packet. */
unsigned long omcl_misaligned_masks(void);

#ifdef __cplusplus
}
#endif

#endif
