/* Box user geometry for Embree 3, and packet tracing of ray arrays.
 * See omcl_embree.h. Every function here is total: no allocation, no abort. */
#include "omcl_embree.h"

#include <math.h>
#include <stdbool.h>
#include <sys/types.h>
#include <string.h>
#include <xmmintrin.h>
#include <pmmintrin.h>

/* Field offsets of RTCRayHitN / RTCHitN in SoA layout (rtcore_ray.h; the
 * accessor helpers there are C++ only). */
#define RAY_F(r, N, field, i) (((float *)(r))[(field) * (N) + (i)])
#define RAY_U(r, N, field, i) (((unsigned *)(r))[(field) * (N) + (i)])
enum { ORG_X, ORG_Y, ORG_Z, TNEAR, DIR_X, DIR_Y, DIR_Z, TIME, TFAR, MASK, ID, FLAGS };
enum { NG_X, NG_Y, NG_Z, HIT_U, HIT_V, PRIM_ID, GEOM_ID, INST_ID };

static void box_bounds(const struct RTCBoundsFunctionArguments *args) {
  const OmclBoxes *b = (const OmclBoxes *)args->geometryUserPtr;
  const float *lo = b->lower + 3 * (size_t)args->primID;
  struct RTCBounds *o = args->bounds_o;
  o->lower_x = lo[0];
  o->lower_y = lo[1];
  o->lower_z = lo[2];
  o->upper_x = lo[0] + b->size;
  o->upper_y = lo[1] + b->size;
  o->upper_z = lo[2] + b->size;
}

/* Slab test of a closed box. Returns the entry distance clamped to tnear
 * (a ray that starts inside the box hits it at tnear) and the axis of entry
 * (-1 when starting inside), or INFINITY for a miss. A zero direction
 * component is handled explicitly so that 0 * inf never makes a NaN. */
static inline float slab(const float lo[3], float size, const float org[3],
                         const float dir[3], float tnear, float tfar, int *axis) {
  float t0 = tnear, t1 = tfar;
  *axis = -1;
  for (int a = 0; a < 3; ++a) {
    float l = lo[a], h = lo[a] + size;
    if (dir[a] == 0.0f) {
      if (org[a] < l || org[a] > h) return INFINITY;
      continue;
    }
    float inv = 1.0f / dir[a];
    float ta = (l - org[a]) * inv, tb = (h - org[a]) * inv;
    if (ta > tb) { float s = ta; ta = tb; tb = s; }
    if (ta > t0) { t0 = ta; *axis = a; }
    if (tb < t1) t1 = tb;
    if (t0 > t1) return INFINITY;
  }
  return t0;
}

static void box_intersect(const struct RTCIntersectFunctionNArguments *args) {
  const OmclBoxes *b = (const OmclBoxes *)args->geometryUserPtr;
  const float *lo = b->lower + 3 * (size_t)args->primID;
  const unsigned N = args->N;
  struct RTCRayHitN *rh = args->rayhit;
  float *hit = (float *)rh + 12 * N;
  for (unsigned i = 0; i < N; ++i) {
    if (!args->valid[i]) continue;
    float org[3] = {RAY_F(rh, N, ORG_X, i), RAY_F(rh, N, ORG_Y, i), RAY_F(rh, N, ORG_Z, i)};
    float dir[3] = {RAY_F(rh, N, DIR_X, i), RAY_F(rh, N, DIR_Y, i), RAY_F(rh, N, DIR_Z, i)};
    float tnear = RAY_F(rh, N, TNEAR, i), tfar = RAY_F(rh, N, TFAR, i);
    int axis;
    float t = slab(lo, b->size, org, dir, tnear, tfar, &axis);
    if (t == INFINITY) continue; /* slab() only accepts t <= current tfar */
    RAY_F(rh, N, TFAR, i) = t;
    float ng[3] = {0.0f, 0.0f, 0.0f};
    if (axis >= 0) ng[axis] = dir[axis] > 0.0f ? -1.0f : 1.0f;
    RAY_F(hit, N, NG_X, i) = ng[0];
    RAY_F(hit, N, NG_Y, i) = ng[1];
    RAY_F(hit, N, NG_Z, i) = ng[2];
    RAY_F(hit, N, HIT_U, i) = 0.0f;
    RAY_F(hit, N, HIT_V, i) = 0.0f;
    RAY_U(hit, N, PRIM_ID, i) = args->primID;
    RAY_U(hit, N, GEOM_ID, i) = args->geomID;
    RAY_U(hit, N, INST_ID, i) = args->context->instID[0];
  }
}

static void box_occluded(const struct RTCOccludedFunctionNArguments *args) {
  const OmclBoxes *b = (const OmclBoxes *)args->geometryUserPtr;
  const float *lo = b->lower + 3 * (size_t)args->primID;
  const unsigned N = args->N;
  struct RTCRayN *r = args->ray;
  for (unsigned i = 0; i < N; ++i) {
    if (!args->valid[i]) continue;
    float org[3] = {RAY_F(r, N, ORG_X, i), RAY_F(r, N, ORG_Y, i), RAY_F(r, N, ORG_Z, i)};
    float dir[3] = {RAY_F(r, N, DIR_X, i), RAY_F(r, N, DIR_Y, i), RAY_F(r, N, DIR_Z, i)};
    int axis;
    float t = slab(lo, b->size, org, dir, RAY_F(r, N, TNEAR, i), RAY_F(r, N, TFAR, i), &axis);
    if (t != INFINITY) RAY_F(r, N, TFAR, i) = -INFINITY; /* Embree's "occluded" mark */
  }
}

/* Mirrors Ray::is_valid on the Rust side: Embree asserts on rays with
 * coordinates beyond 1.8e18 or NaN bounds, so such rays are masked out. */
static inline int ray_ok(const OmclRay *r) {
  const float large = 1e18f;
  int nonzero = 0;
  for (int a = 0; a < 3; ++a) {
    if (!(fabsf(r->org[a]) <= large) || !(fabsf(r->dir[a]) <= large)) return 0;
    nonzero |= r->dir[a] != 0.0f;
  }
  return nonzero && !isnan(r->tnear) && !isnan(r->tfar);
}

void omcl_set_box_callbacks(RTCGeometry geom, const OmclBoxes *boxes) {
  rtcSetGeometryUserPrimitiveCount(geom, boxes->count);
  rtcSetGeometryUserData(geom, (void *)boxes);
  rtcSetGeometryBoundsFunction(geom, box_bounds, NULL);
  rtcSetGeometryIntersectFunction(geom, box_intersect);
  rtcSetGeometryOccludedFunction(geom, box_occluded);
}

static _Thread_local int last_code = RTC_ERROR_NONE;
static _Thread_local char last_msg[256];

static void on_error(void *user, enum RTCError code, const char *msg) {
  (void)user;
  last_code = (int)code;
  strncpy(last_msg, msg ? msg : "", sizeof last_msg - 1);
  last_msg[sizeof last_msg - 1] = '\0';
}

void omcl_install_error_handler(RTCDevice device) {
  rtcSetDeviceErrorFunction(device, on_error, NULL);
}

int omcl_take_error(char *buf, size_t len) {
  int code = last_code;
  if (buf && len) {
    strncpy(buf, last_msg, len - 1);
    buf[len - 1] = '\0';
  }
  last_code = RTC_ERROR_NONE;
  last_msg[0] = '\0';
  return code;
}

static bool count_memory(void *user, ssize_t bytes, bool post) {
  (void)post;
  __atomic_fetch_add((int64_t *)user, (int64_t)bytes, __ATOMIC_RELAXED);
  return true;
}

void omcl_install_memory_monitor(RTCDevice device, int64_t *counter) {
  rtcSetDeviceMemoryMonitorFunction(device, count_memory, counter);
}

void omcl_set_ftz_daz(void) {
  _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
  _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

#define TRACE_PACKET(W, TYPE, FN)                                              \
  static void trace_##W(RTCScene scene, struct RTCIntersectContext *ctx,      \
                        const OmclRay *rays, OmclHit *hits, size_t n) {       \
    for (size_t s = 0; s < n; s += W) {                                        \
      size_t m = n - s < W ? n - s : W;                                        \
      TYPE p;                                                                  \
      const OmclRay safe_ray = {{0, 0, 0}, {1, 0, 0}, 0.0f, 0.0f};             \
      int valid[W];                                                            \
      for (size_t i = 0; i < W; ++i) {                                         \
        const OmclRay *r = &rays[s + (i < m ? i : 0)];                         \
        valid[i] = (i < m && ray_ok(r)) ? -1 : 0;                              \
        if (!valid[i]) r = &safe_ray;                                          \
        p.ray.org_x[i] = r->org[0]; p.ray.org_y[i] = r->org[1];                \
        p.ray.org_z[i] = r->org[2]; p.ray.dir_x[i] = r->dir[0];                \
        p.ray.dir_y[i] = r->dir[1]; p.ray.dir_z[i] = r->dir[2];                \
        p.ray.tnear[i] = r->tnear; p.ray.tfar[i] = r->tfar;                    \
        p.ray.time[i] = 0.0f; p.ray.mask[i] = 0xFFFFFFFFu;                     \
        p.ray.id[i] = (unsigned)i; p.ray.flags[i] = 0;                         \
        p.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;                             \
        p.hit.primID[i] = RTC_INVALID_GEOMETRY_ID;                             \
        p.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;                          \
      }                                                                        \
      FN(valid, scene, ctx, &p);                                               \
      for (size_t i = 0; i < m; ++i) {                                         \
        OmclHit *h = &hits[s + i];                                             \
        if (p.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) {                      \
          h->prim = OMCL_NO_HIT; h->geom = OMCL_NO_HIT; h->t = INFINITY;       \
        } else {                                                               \
          h->prim = p.hit.primID[i]; h->geom = p.hit.geomID[i];                \
          h->t = p.ray.tfar[i];                                                \
        }                                                                      \
      }                                                                        \
    }                                                                          \
  }

TRACE_PACKET(4, struct RTCRayHit4, rtcIntersect4)
TRACE_PACKET(8, struct RTCRayHit8, rtcIntersect8)
TRACE_PACKET(16, struct RTCRayHit16, rtcIntersect16)

static void trace_1(RTCScene scene, struct RTCIntersectContext *ctx,
                    const OmclRay *rays, OmclHit *hits, size_t n) {
  for (size_t s = 0; s < n; ++s) {
    const OmclRay *r = &rays[s];
    OmclHit *h = &hits[s];
    if (!ray_ok(r)) {
      h->prim = OMCL_NO_HIT; h->geom = OMCL_NO_HIT; h->t = INFINITY;
      continue;
    }
    struct RTCRayHit p;
    p.ray.org_x = r->org[0]; p.ray.org_y = r->org[1]; p.ray.org_z = r->org[2];
    p.ray.dir_x = r->dir[0]; p.ray.dir_y = r->dir[1]; p.ray.dir_z = r->dir[2];
    p.ray.tnear = r->tnear; p.ray.tfar = r->tfar; p.ray.time = 0.0f;
    p.ray.mask = 0xFFFFFFFFu; p.ray.id = 0; p.ray.flags = 0;
    p.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    p.hit.primID = RTC_INVALID_GEOMETRY_ID;
    p.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(scene, ctx, &p);
    if (p.hit.geomID == RTC_INVALID_GEOMETRY_ID) {
      h->prim = OMCL_NO_HIT; h->geom = OMCL_NO_HIT; h->t = INFINITY;
    } else {
      h->prim = p.hit.primID; h->geom = p.hit.geomID; h->t = p.ray.tfar;
    }
  }
}

/* Ray streams: Embree regroups the rays itself (rtcIntersect1M). */
static void trace_stream(RTCScene scene, struct RTCIntersectContext *ctx,
                         const OmclRay *rays, OmclHit *hits, size_t n) {
  enum { M = 256 };
  struct RTCRayHit buf[M];
  for (size_t s = 0; s < n; s += M) {
    size_t m = n - s < M ? n - s : M;
    for (size_t i = 0; i < m; ++i) {
      const OmclRay *r = &rays[s + i];
      struct RTCRayHit *p = &buf[i];
      int ok = ray_ok(r);
      p->ray.org_x = ok ? r->org[0] : 0.0f; p->ray.org_y = ok ? r->org[1] : 0.0f;
      p->ray.org_z = ok ? r->org[2] : 0.0f; p->ray.dir_x = ok ? r->dir[0] : 1.0f;
      p->ray.dir_y = ok ? r->dir[1] : 0.0f; p->ray.dir_z = ok ? r->dir[2] : 0.0f;
      p->ray.tnear = ok ? r->tnear : 0.0f;
      p->ray.tfar = ok ? r->tfar : -INFINITY; /* tfar < tnear: inactive */
      p->ray.time = 0.0f; p->ray.mask = 0xFFFFFFFFu; p->ray.id = (unsigned)i;
      p->ray.flags = 0;
      p->hit.geomID = RTC_INVALID_GEOMETRY_ID;
      p->hit.primID = RTC_INVALID_GEOMETRY_ID;
      p->hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect1M(scene, ctx, buf, (unsigned)m, sizeof(struct RTCRayHit));
    for (size_t i = 0; i < m; ++i) {
      OmclHit *h = &hits[s + i];
      if (buf[i].hit.geomID == RTC_INVALID_GEOMETRY_ID) {
        h->prim = OMCL_NO_HIT; h->geom = OMCL_NO_HIT; h->t = INFINITY;
      } else {
        h->prim = buf[i].hit.primID; h->geom = buf[i].hit.geomID; h->t = buf[i].ray.tfar;
      }
    }
  }
}

void omcl_trace(RTCScene scene, const OmclRay *rays, OmclHit *hits, size_t n,
                unsigned packet) {
  omcl_set_ftz_daz();
  struct RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  switch (packet) {
    case 16: trace_16(scene, &ctx, rays, hits, n); break;
    case 8: trace_8(scene, &ctx, rays, hits, n); break;
    case 4: trace_4(scene, &ctx, rays, hits, n); break;
    case 0: trace_stream(scene, &ctx, rays, hits, n); break;
    default: trace_1(scene, &ctx, rays, hits, n); break;
  }
}
