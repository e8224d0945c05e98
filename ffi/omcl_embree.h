/* The C side of omcl's Embree interop.
 *
 * bindgen reads this header: it pulls in Embree 3's public API (`rtc*`) and
 * declares the small shim below, compiled from omcl_embree.c by `cc`.
 * Voxels are axis-aligned cubes of edge `size` whose lower corners are given
 * in the map's grid frame (world minus map origin, metres, float).
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

/* One ray in, one hit out (array-of-structs on the Rust side). */
typedef struct OmclRay {
  float org[3];
  float dir[3];
  float tnear;
  float tfar;
} OmclRay;

typedef struct OmclHit {
  uint32_t prim; /* box index, or OMCL_NO_HIT */
  uint32_t geom; /* geometry id, or OMCL_NO_HIT */
  float t;       /* distance along dir (in units of |dir|) */
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
 * as Embree ray streams for packet 0;
 * sets FTZ/DAZ on the calling thread first. */
void omcl_trace(RTCScene scene, const OmclRay *rays, OmclHit *hits, size_t n,
                unsigned packet);

#ifdef __cplusplus
}
#endif

#endif
