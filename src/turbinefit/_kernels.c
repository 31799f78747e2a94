/*
 * turbinefit's compiled kernels: the image terms of the joint least-squares problem
 * (projection, bicubic heat-map cost or 2-D correspondence, their Newton model, and the
 * per-keyframe normal-equation blocks), the correspondence searches, and the
 * block-tridiagonal solve of the pose chain.
 *
 * Each function mirrors a numpy reference in the package exactly (same formulas, same
 * clamping, same order of decisions); tests compare the two. They are written in C
 * because the numpy versions spend their time on temporaries of shape (N, M, 2, 13) and
 * on per-keyframe gathers from separate memory maps, while here each sample is projected,
 * interpolated and folded into its keyframe's 13 x 13 block in registers. Keyframes are
 * independent, so the loops over them run in parallel with OpenMP where available.
 *
 * Conventions (see the Python modules): poses are world_T_cam as wxyz + xyz; a camera
 * point is R^T (p - t); the local pose update is t + dt, R Exp(dphi); Jacobian columns are
 * (dt[3], dphi[3], theta[7]). Heat-maps are float32 (7, H, W), element [c, i, j] at
 * u = j, v = i; or float16 (a flight's maps share one storage, `half`), read through
 * half_value. Loaded with ctypes (no Python C API).
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifndef _WIN32
#include <sys/mman.h>
#include <unistd.h>
#define TF_HAVE_MMAP 1
#endif

#ifdef _OPENMP
#include <omp.h>
#endif

#ifdef _WIN32
#define TF_EXPORT __declspec(dllexport)
#else
#define TF_EXPORT __attribute__((visibility("default")))
#endif

#define MIN_DEPTH 0.1
#define G_MIN 1e-4
#define NCOL 13

/* ---- camera ------------------------------------------------------------------- */

typedef struct {
    double fx, fy, cx, cy, skew, k1, k2, p1, p2, k3, r2max;
    int width, height, has_dist;
} Camera;

static Camera camera_from(const double *c, int width, int height) {
    Camera cam;
    cam.fx = c[0]; cam.fy = c[1]; cam.cx = c[2]; cam.cy = c[3]; cam.skew = c[4];
    cam.k1 = c[5]; cam.k2 = c[6]; cam.p1 = c[7]; cam.p2 = c[8]; cam.k3 = c[9];
    cam.r2max = c[10];
    cam.width = width; cam.height = height;
    cam.has_dist = (cam.k1 != 0.0 || cam.k2 != 0.0 || cam.p1 != 0.0 || cam.p2 != 0.0
                    || cam.k3 != 0.0);
    return cam;
}

/* Project camera point P; uv and (if Juv) d uv / d P (2x3, row-major). Returns front. */
static int project(const Camera *cam, const double P[3], double uv[2], double *Juv) {
    double X = P[0], Y = P[1], Z = P[2];
    int front = Z > MIN_DEPTH;
    double inv_z = 1.0 / (front ? Z : 1.0);
    double x = X * inv_z, y = Y * inv_z;
    double r2 = x * x + y * y;
    int in_range = r2 < cam->r2max;
    double xd = x, yd = y, radial = 1.0;
    if (cam->has_dist) {
        radial = 1.0 + r2 * (cam->k1 + r2 * (cam->k2 + r2 * cam->k3));
        xd = x * radial + 2 * cam->p1 * x * y + cam->p2 * (r2 + 2 * x * x);
        yd = y * radial + cam->p1 * (r2 + 2 * y * y) + 2 * cam->p2 * x * y;
    }
    uv[0] = cam->fx * xd + cam->skew * yd + cam->cx;
    uv[1] = cam->fy * yd + cam->cy;
    front = front && in_range;
    if (Juv) {
        double dxd_dx = 1.0, dxd_dy = 0.0, dyd_dx = 0.0, dyd_dy = 1.0;
        if (cam->has_dist) {
            double dr = cam->k1 + r2 * (2 * cam->k2 + 3 * cam->k3 * r2);
            dxd_dx = radial + 2 * x * x * dr + 2 * cam->p1 * y + 6 * cam->p2 * x;
            dxd_dy = 2 * x * y * dr + 2 * cam->p1 * x + 2 * cam->p2 * y;
            dyd_dx = dxd_dy;
            dyd_dy = radial + 2 * y * y * dr + 6 * cam->p1 * y + 2 * cam->p2 * x;
        }
        double du_dx = cam->fx * dxd_dx + cam->skew * dyd_dx;
        double du_dy = cam->fx * dxd_dy + cam->skew * dyd_dy;
        double dv_dx = cam->fy * dyd_dx;
        double dv_dy = cam->fy * dyd_dy;
        if (front) {
            Juv[0] = du_dx * inv_z;
            Juv[1] = du_dy * inv_z;
            Juv[2] = -(du_dx * x + du_dy * y) * inv_z;
            Juv[3] = dv_dx * inv_z;
            Juv[4] = dv_dy * inv_z;
            Juv[5] = -(dv_dx * x + dv_dy * y) * inv_z;
        } else {
            for (int i = 0; i < 6; i++) Juv[i] = 0.0;
        }
    }
    return front;
}

static int in_image(const Camera *cam, const double uv[2]) {
    return uv[0] >= 0.0 && uv[0] <= cam->width - 1 && uv[1] >= 0.0 && uv[1] <= cam->height - 1;
}

static void quat_to_R(const double *q, double R[9]) {
    double w = q[0], x = q[1], y = q[2], z = q[3];
    R[0] = 1 - 2 * (y * y + z * z); R[1] = 2 * (x * y - w * z); R[2] = 2 * (x * z + w * y);
    R[3] = 2 * (x * y + w * z); R[4] = 1 - 2 * (x * x + z * z); R[5] = 2 * (y * z - w * x);
    R[6] = 2 * (x * z - w * y); R[7] = 2 * (y * z + w * x); R[8] = 1 - 2 * (x * x + y * y);
}

/* ---- bicubic (Catmull-Rom) ------------------------------------------------------- */

static void cr_weights(double t, double w[4], double dw[4], double d2w[4]) {
    double t2 = t * t, t3 = t2 * t;
    w[0] = 0.5 * (-t3 + 2 * t2 - t); w[1] = 0.5 * (3 * t3 - 5 * t2 + 2);
    w[2] = 0.5 * (-3 * t3 + 4 * t2 + t); w[3] = 0.5 * (t3 - t2);
    dw[0] = 0.5 * (-3 * t2 + 4 * t - 1); dw[1] = 0.5 * (9 * t2 - 10 * t);
    dw[2] = 0.5 * (-9 * t2 + 8 * t + 1); dw[3] = 0.5 * (3 * t2 - 2 * t);
    d2w[0] = -3 * t + 2; d2w[1] = 9 * t - 5; d2w[2] = -9 * t + 4; d2w[3] = 3 * t - 1;
}

static inline int clampi(int v, int lo, int hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* fmax and fmin (a NaN argument gives the other), inlined: the library's are calls, four
 * of them in each bilinear sample of the line search. */
static inline double maxd(double a, double b) { return (a > b || b != b) ? a : b; }
static inline double mind(double a, double b) { return (a < b || b != b) ? a : b; }

/* One half-precision value as float32, exactly (numpy's conversion; a NaN stays a NaN):
 * the 15 bits of exponent and mantissa moved to float32's places and scaled by 2^112,
 * which rebiases the exponent of normal and subnormal values alike; infinities and NaNs
 * (exponent all ones) get float32's all-ones exponent. Branch-free (the value check's
 * loop over a keyframe vectorises). */
static inline float half_value(uint16_t h) {
    union { uint32_t u; float f; } o, magic, infnan;
    magic.u = (uint32_t)(254 - 15) << 23;  /* 2^112 */
    infnan.u = (uint32_t)(127 + 16) << 23; /* 65536: half's largest exponent, rebiased */
    o.u = (uint32_t)(h & 0x7fff) << 13;
    o.f *= magic.f;
    o.u |= (o.f >= infnan.f) ? (uint32_t)255 << 23 : 0u;
    o.u |= (uint32_t)(h & 0x8000) << 16;
    return o.f;
}

/* ---- the value check of heat-maps --------------------------------------------------- */

/* The values a heat-map may hold, [lo, hi] in float32, and for float16 the magnitudes (15
 * bits) in range for each sign, [a0, b0] and [a1, b1] (empty if a > b): a half's value
 * grows with its magnitude bits, and NaNs (above 0x7c00) lie beyond every range, so the
 * check of float16 compares integers. */
typedef struct {
    float lo, hi;
    int16_t a0, b0, a1, b1;
} ValueRange;

static ValueRange value_range(double lo, double hi, int64_t half) {
    ValueRange r;
    r.lo = (float)lo;
    r.hi = (float)hi;
    r.a0 = 0x7fff; r.b0 = 0; r.a1 = 0x7fff; r.b1 = 0; /* empty unless found below */
    for (int16_t m = 0; half && m <= 0x7c00; m++) {
        const float v = half_value((uint16_t)m);
        if (v >= r.lo && v <= r.hi) { if (r.a0 > m) r.a0 = m; r.b0 = m; }
        if (-v >= r.lo && -v <= r.hi) { if (r.a1 > m) r.a1 = m; r.b1 = m; }
    }
    return r;
}

/* Whether `count` values at p (float16 if half) hold a NaN or a value outside r. */
static int out_of_range(const void *p, int64_t half, int64_t count, const ValueRange *r) {
    if (half) {
        const uint16_t *q = (const uint16_t *)p;
        const int16_t a0 = r->a0, b0 = r->b0, a1 = r->a1, b1 = r->b1;
        int16_t acc = 0; /* 16-bit lanes throughout, so that the loop vectorises */
        for (int64_t i = 0; i < count; i++) {
            const int16_t x = (int16_t)q[i], m = (int16_t)(x & 0x7fff);
            const int16_t neg = (int16_t)(x >> 15); /* 0 or -1: all bits set */
            const int16_t lo_m = (int16_t)((a0 & ~neg) | (a1 & neg));
            const int16_t hi_m = (int16_t)((b0 & ~neg) | (b1 & neg));
            acc |= (int16_t)((m < lo_m) | (m > hi_m));
        }
        return acc != 0;
    }
    const float *f = (const float *)p;
    const float flo = r->lo, fhi = r->hi;
    int bad = 0;
    for (int64_t i = 0; i < count; i++) {
        const float v = f[i];
        bad |= !(v >= flo) | !(v <= fhi);
    }
    return bad;
}

/* ---- heat-map files, mapped, holding only the pages read ----------------------------
 *
 * A flight's heat-map files are mapped read-only, one mapping per keyframe, and the
 * kernels read them in place. A fit reads a quarter to a third of their pages (the bands
 * round the projected model), but the kernel's fault-around maps the pages next to each
 * one read (64 kB at a time on Linux), which over a fit is in effect all of them, and
 * every mapped page counts in the process's memory. So the kernels note each page they
 * read (`used`), and when a kernel is done with a keyframe that read a page for the first
 * time, the pages mapped round it that nothing read are dropped again (madvise
 * MADV_DONTNEED: they stay in the page cache, and a later read maps them back). The
 * process then holds the pages read, and the pages of a keyframe or two per thread. The
 * value check reads each file whole and drops it at once (tf_files_check). */

/* Relaxed loads and stores of the page notes (GCC, Clang; MSVC maps no files). */
#ifdef _MSC_VER
#define LOAD_U8(p) (*(volatile uint8_t *)(p))
#define STORE_U8(p, v) (*(volatile uint8_t *)(p) = (v))
#define LOAD_I64(p) (*(volatile int64_t *)(p))
static int cas_i64(int64_t *p, int64_t *expected, int64_t v) {
    if (*p != *expected) { *expected = *p; return 0; }
    *p = v;
    return 1;
}
#define CAS_I64(p, e, v) cas_i64((p), (e), (v))
#else
#define LOAD_U8(p) __atomic_load_n((p), __ATOMIC_RELAXED)
#define STORE_U8(p, v) __atomic_store_n((p), (v), __ATOMIC_RELAXED)
#define LOAD_I64(p) __atomic_load_n((p), __ATOMIC_ACQUIRE)
#define CAS_I64(p, e, v) \
    __atomic_compare_exchange_n((p), (e), (v), 0, __ATOMIC_ACQ_REL, __ATOMIC_ACQUIRE)
#endif

typedef struct {
    int64_t n, count, half, itemsize, page_shift, npages;
    char **base;          /* per keyframe: its mapping (from the file's start) */
    size_t *length;       /* per keyframe: bytes mapped */
    int64_t *offset;      /* per keyframe: where its values start */
    uint8_t *used;        /* n * npages: pages a kernel read */
    uint8_t *dirty;       /* n: a page read for the first time since the last trim */
    /* the value check (tf_files_check_setup) */
    uint8_t *checked;     /* n: 1 once the keyframe's values were checked, 2 if bad */
    int64_t first_bad;    /* the first keyframe found out of range (n if none) */
    ValueRange range;
    int64_t height, width, nrows, ncols, step, channels, on_first_read;
    int64_t *rows;        /* the coarse grid's rows */
    char *grid;           /* n * channels * nrows * ncols values: the coarse grid */
} TfFiles;

TF_EXPORT void tf_files_free(void *handle);

/* Runs of unread pages shorter than this many bytes stay mapped: the kernel's fault-around
 * (64 kB) maps such a gap back with its next read nearby, and each drop is a system call
 * (and a TLB flush on every thread's processor). A 1000-keyframe fit then holds a few
 * tens of per cent more than the pages it reads, with a third of the calls. */
#define TRIM_MIN_BYTES ((int64_t)64 << 10)

/* Drop the pages of keyframe k that no kernel read. */
static void files_drop(TfFiles *fl, int64_t k) {
#ifdef TF_HAVE_MMAP
    const uint8_t *used = fl->used + k * fl->npages;
    const int64_t pages = (int64_t)((fl->length[k] + ((size_t)1 << fl->page_shift) - 1)
                                    >> fl->page_shift);
    const int64_t min_run = TRIM_MIN_BYTES >> fl->page_shift;
    int64_t p = 0;
    while (p < pages) {
        while (p < pages && LOAD_U8(used + p)) p++;
        const int64_t start = p;
        while (p < pages && !LOAD_U8(used + p)) p++;
        if (p > start && p - start >= min_run)
            madvise(fl->base[k] + (start << fl->page_shift),
                    (size_t)((p - start) << fl->page_shift), MADV_DONTNEED);
    }
#else
    (void)fl; (void)k;
#endif
}

/* Check keyframe k's values (reading them all through its mapping) and keep its coarse
 * grid; a keyframe out of range lowers first_bad. Its pages stay mapped (dirty: the
 * caller drops what it does not read). */
static void check_keyframe(TfFiles *fl, int64_t k) {
    const char *buf = fl->base[k] + fl->offset[k];
    const int64_t isz = fl->itemsize, H = fl->height, W = fl->width;
    const int bad = out_of_range(buf, fl->half, fl->count, &fl->range);
    if (bad) {
        int64_t cur = LOAD_I64(&fl->first_bad);
        while (k < cur && !CAS_I64(&fl->first_bad, &cur, k)) {}
    } else if (fl->grid != NULL) {
        char *g = fl->grid + k * fl->channels * fl->nrows * fl->ncols * isz;
        for (int64_t c = 0; c < fl->channels; c++)
            for (int64_t i = 0; i < fl->nrows; i++) {
                const char *row = buf + ((c * H + fl->rows[i]) * W) * isz;
                for (int64_t j = 0; j < fl->ncols; j++, g += isz)
                    memcpy(g, row + j * fl->step * isz, (size_t)isz);
            }
    }
    STORE_U8(fl->checked + k, bad ? 2 : 1);
    fl->dirty[k] = 1;
}

/* Before a kernel reads keyframe k: with the check on first read, check it now (the same
 * pass brings in the pages the kernel reads next). */
static inline void files_touch(const void *files, uint64_t k) {
    TfFiles *fl = (TfFiles *)files;
    if (fl != NULL && fl->on_first_read && !LOAD_U8(fl->checked + k))
        check_keyframe(fl, (int64_t)k);
}

/* After a kernel is done with keyframe k (its index among the files): drop the pages
 * mapped round the ones it read for the first time. */
static void files_trim(const void *files, uint64_t k) {
    TfFiles *fl = (TfFiles *)files;
    if (fl == NULL || !fl->dirty[k]) return;
    fl->dirty[k] = 0;
    files_drop(fl, (int64_t)k);
}

/* Map N keyframes' heat-map files (descriptors fds, which the caller may close at once;
 * values from offsets[k], `count` each, float16 if `half` else float32). Returns the
 * handle, or 0 with errno set (no mapping or memory; no mmap on this platform). */
TF_EXPORT void *tf_files_new(int64_t n, const int64_t *fds, const int64_t *offsets,
                             int64_t count, int64_t half) {
#ifndef TF_HAVE_MMAP
    (void)n; (void)fds; (void)offsets; (void)count; (void)half;
    errno = ENOSYS;
    return NULL;
#else
    TfFiles *fl = (TfFiles *)calloc(1, sizeof(TfFiles));
    if (fl == NULL) return NULL;
    fl->n = n;
    fl->count = count;
    fl->half = half;
    fl->itemsize = half ? 2 : 4;
    long page = sysconf(_SC_PAGESIZE);
    fl->page_shift = 12;
    while (page > 0 && ((int64_t)1 << fl->page_shift) < page) fl->page_shift++;
    const size_t m = (size_t)(n > 0 ? n : 1);
    fl->base = (char **)calloc(m, sizeof(char *));
    fl->length = (size_t *)calloc(m, sizeof(size_t));
    fl->offset = (int64_t *)calloc(m, sizeof(int64_t));
    fl->dirty = (uint8_t *)calloc(m, 1);
    fl->checked = (uint8_t *)calloc(m, 1);
    fl->first_bad = n;
    int64_t most = 0;
    for (int64_t k = 0; k < n; k++)
        if (offsets[k] > most) most = offsets[k];
    fl->npages = (most + count * fl->itemsize + ((int64_t)1 << fl->page_shift) - 1)
                 >> fl->page_shift;
    fl->used = (uint8_t *)calloc(m * (size_t)fl->npages, 1);
    int ok = fl->base && fl->length && fl->offset && fl->dirty && fl->used && fl->checked;
    for (int64_t k = 0; ok && k < n; k++) {
        fl->offset[k] = offsets[k];
        fl->length[k] = (size_t)(offsets[k] + count * fl->itemsize);
        void *p = mmap(NULL, fl->length[k], PROT_READ, MAP_SHARED, (int)fds[k], 0);
        if (p == MAP_FAILED) ok = 0;
        else fl->base[k] = (char *)p;
    }
    if (!ok) {
        int err = errno ? errno : ENOMEM;
        tf_files_free(fl);
        errno = err;
        return NULL;
    }
    return fl;
#endif
}

/* Unmap the files. */
TF_EXPORT void tf_files_free(void *handle) {
    TfFiles *fl = (TfFiles *)handle;
    if (fl == NULL) return;
#ifdef TF_HAVE_MMAP
    for (int64_t k = 0; fl->base && k < fl->n; k++)
        if (fl->base[k] != NULL) munmap(fl->base[k], fl->length[k]);
#endif
    free(fl->base); free(fl->length); free(fl->offset); free(fl->used); free(fl->dirty);
    free(fl->checked); free(fl->rows); free(fl);
}

/* Pages the kernels read so far (the bytes the process holds of the files). */
TF_EXPORT int64_t tf_files_used(const void *handle) {
    const TfFiles *fl = (const TfFiles *)handle;
    int64_t total = 0;
    for (int64_t i = 0; i < fl->n * fl->npages; i++) total += fl->used[i];
    return total << fl->page_shift;
}

/* Copy keyframe k's values into out (count values), holding no page of it but those the
 * kernels read; with the check on first read, checked first. */
TF_EXPORT void tf_files_read(void *handle, int64_t k, void *out) {
    TfFiles *fl = (TfFiles *)handle;
    files_touch(fl, (uint64_t)k);
    memcpy(out, fl->base[k] + fl->offset[k], (size_t)(fl->count * fl->itemsize));
    fl->dirty[k] = 0;
    files_drop(fl, k);
}

/* One channel plane of a keyframe's heat-maps, stored as float32 or float16 (the maps of
 * a flight share one storage; float16 values are read through half_value); with files,
 * the kernels note the values they read (mark, exactly: a page noted but not read would
 * not be let go if a later read of it mapped its neighbours). */
typedef struct {
    const float *f;
    const uint16_t *h;
    uint8_t *used;     /* files: the keyframe's row of TfFiles.used, else NULL */
    uint8_t *dirty;    /* files: the keyframe's TfFiles.dirty */
    size_t first;      /* files: the byte of the plane's first value in its file */
    int64_t isz, page_shift;
} Plane;

/* The plane that starts `offset` values into the maps of keyframe `addr`: the address of
 * its array or, with `files`, its index among them. */
static inline Plane plane_at(uint64_t addr, int64_t half, const void *files, size_t offset) {
    Plane p;
    const TfFiles *fl = (const TfFiles *)files;
    const char *data = fl ? fl->base[addr] + fl->offset[addr] : (const char *)(uintptr_t)addr;
    p.f = half ? NULL : (const float *)data + offset;
    p.h = half ? (const uint16_t *)data + offset : NULL;
    p.used = fl ? fl->used + (int64_t)addr * fl->npages : NULL;
    p.dirty = fl ? fl->dirty + addr : NULL;
    p.isz = half ? 2 : 4;
    p.first = fl ? (size_t)fl->offset[addr] + offset * (size_t)p.isz : 0;
    p.page_shift = fl ? fl->page_shift : 0;
    return p;
}

/* Note that values i0..i1 (one run, i0 <= i1) of a plane are read (files only): their
 * pages are then kept. */
static inline void mark(Plane p, size_t i0, size_t i1) {
    if (p.used == NULL) return;
    const size_t a = (p.first + i0 * (size_t)p.isz) >> p.page_shift;
    const size_t b = (p.first + i1 * (size_t)p.isz + (size_t)p.isz - 1) >> p.page_shift;
    for (size_t q = a; q <= b; q++)
        if (!LOAD_U8(p.used + q)) {
            STORE_U8(p.used + q, 1);
            *p.dirty = 1;
        }
}

/* Value i of a plane. */
static inline double at(Plane p, size_t i) {
    return p.h ? (double)half_value(p.h[i]) : (double)p.f[i];
}

/* Value, gradient (du, dv) and Hessian (uu, uv, vv) of one channel plane at (u, v).
 * Returns 0, or 1 if a tap is not finite. */
static int bicubic(Plane plane, int W, int H, double u, double v, double *G,
                   double dG[2], double hG[3]) {
    u = mind(maxd(u, -1.0), (double)W);
    v = mind(maxd(v, -1.0), (double)H);
    double u0 = floor(u), v0 = floor(v);
    double wu[4], dwu[4], d2wu[4], wv[4], dwv[4], d2wv[4];
    cr_weights(u - u0, wu, dwu, d2wu);
    cr_weights(v - v0, wv, dwv, d2wv);
    int iu = (int)u0, iv = (int)v0;
    int cols[4];
    for (int j = 0; j < 4; j++) cols[j] = clampi(iu - 1 + j, 0, W - 1);
    double val = 0, gu = 0, gv = 0, huu = 0, huv = 0, hvv = 0;
    int bad = 0;
    for (int i = 0; i < 4; i++) {
        const size_t row = (size_t)clampi(iv - 1 + i, 0, H - 1) * W;
        mark(plane, row + cols[0], row + cols[3]);
        double pu = 0, pdu = 0, pd2u = 0;
        for (int j = 0; j < 4; j++) {
            double p = at(plane, row + cols[j]);
            if (!isfinite(p)) bad = 1;
            pu += p * wu[j];
            pdu += p * dwu[j];
            pd2u += p * d2wu[j];
        }
        val += pu * wv[i];
        gu += pdu * wv[i];
        gv += pu * dwv[i];
        huu += pd2u * wv[i];
        huv += pdu * dwv[i];
        hvv += pu * d2wv[i];
    }
    *G = val;
    if (dG) { dG[0] = gu; dG[1] = gv; }
    if (hG) { hG[0] = huu; hG[1] = huv; hG[2] = hvv; }
    return bad;
}

/* Smooth in-image weight and its gradient (same as heatmap_cost.border_weight). */
static double border_weight(double u, double v, int W, int H, double margin, double grad[2]) {
    double d[4] = {u, W - 1 - u, v, H - 1 - v};
    int which = 0;
    for (int k = 1; k < 4; k++)
        if (d[k] < d[which]) which = k;
    double dmin = d[which];
    grad[0] = grad[1] = 0.0;
    if (margin <= 0) return dmin >= 0 ? 1.0 : 0.0;
    double x = mind(maxd(dmin / margin, 0.0), 1.0);
    double w = x * x * (3.0 - 2.0 * x);
    double dw = (x > 0 && x < 1) ? 6.0 * x * (1.0 - x) / margin : 0.0;
    double sign = (which % 2 == 0) ? 1.0 : -1.0;
    grad[which / 2] = sign * dw;
    return w;
}

/* Nearest PSD matrix of [[a, b], [b, c]] into H (row-major 2x2). */
static void psd2(double a, double b, double c, double H[4]) {
    double m = 0.5 * (a + c);
    double d = sqrt(0.25 * (a - c) * (a - c) + b * b);
    double l1 = m + d, l2 = m - d;
    H[0] = a; H[1] = b; H[2] = b; H[3] = c;
    if (l1 <= 0.0) {
        H[0] = H[1] = H[2] = H[3] = 0.0;
    } else if (l2 < 0.0) {
        double f = l1 / (l1 - l2);
        H[0] = f * (a - l2); H[1] = f * b; H[2] = f * b; H[3] = f * (c - l2);
    }
}

/* Robust loss (robust.py): rho(s) and rho'(s). kind 0 none, 1 huber, 2 cauchy. */
static void robust(int kind, double scale, double s, double *rho, double *drho) {
    double c2 = scale * scale;
    if (kind == 1) {
        if (s <= c2) { *rho = s; *drho = 1.0; }
        else {
            double root = sqrt(maxd(s, 1e-300));
            *rho = 2.0 * scale * root - c2;
            *drho = scale / root;
        }
    } else if (kind == 2) {
        *rho = c2 * log1p(s / c2);
        *drho = 1.0 / (1.0 + s / c2);
    } else {
        *rho = s; *drho = 1.0;
    }
}

/* ---- image terms ------------------------------------------------------------------ */

/*
 * kind 0: interp (heat-map cost, exact PSD Hessian); kind 1: corr, to target (N, M, 2)
 * where found (N, M), 2-D distance, or along normal (N, M, 2) if given.
 * par: lambda, pixel_sigma, margin, floor, robust_kind, robust_scale.
 * Points: p = (1 - f) A + f B, dp/dtheta = (1 - f) JA + f JB, f = frac[n * frac_stride + m]
 * (frac NULL: f = 0). JA/JB NULL: no theta columns (zero).
 * Accumulates into JtHJ (N, 13, 13), g (N, 13), cost (N,), count (N,).
 * Returns -1, or the smallest keyframe row n whose heat-map had a non-finite tap.
 */
TF_EXPORT int64_t tf_image_terms(
    int64_t N, int64_t M, const double *poses, const double *cam_par, int64_t width,
    int64_t height, const double *A, const double *B, const double *JA, const double *JB,
    const double *frac, int64_t frac_stride, const int64_t *channels,
    const uint64_t *maps, int64_t half, const void *files, const int64_t *keyframes, int64_t kind,
    const double *target,
    const uint8_t *found, const double *normal, const double *par, int64_t with_jacobian, double *JtHJ, double *g,
    double *cost, int64_t *count) {
    Camera cam = camera_from(cam_par, (int)width, (int)height);
    const double lam = par[0], sigma = par[1], margin = par[2], floor_ = par[3];
    const int rkind = (int)par[4];
    const double rscale = par[5];
    const double eps = floor_ > G_MIN ? floor_ : G_MIN;
    const double log1p_eps = log1p(eps);
    const int W = (int)width, H = (int)height;
    const size_t plane = (size_t)W * H;
    int64_t first_bad = INT64_MAX;

#pragma omp parallel for schedule(dynamic, 8) reduction(min : first_bad)
    for (int64_t n = 0; n < N; n++) {
        double R[9];
        quat_to_R(poses + 7 * n, R);
        const double *t = poses + 7 * n + 4;
        const uint64_t hm = maps[keyframes[n]];
        files_touch(files, hm);
        double acc[NCOL * NCOL];
        double gacc[NCOL];
        memset(acc, 0, sizeof acc);
        memset(gacc, 0, sizeof gacc);
        double c_n = 0.0;
        int64_t cnt = 0;
        int bad = 0;
        for (int64_t m = 0; m < M; m++) {
            double f = frac ? frac[n * frac_stride + m] : 0.0;
            double p[3], d[3], P[3];
            for (int k = 0; k < 3; k++) {
                p[k] = (1.0 - f) * A[3 * m + k] + f * B[3 * m + k];
                d[k] = p[k] - t[k];
            }
            /* P = R^T d */
            for (int k = 0; k < 3; k++) P[k] = R[k] * d[0] + R[3 + k] * d[1] + R[6 + k] * d[2];
            double uv[2], Juv[6];
            int front = project(&cam, P, uv, with_jacobian ? Juv : NULL);
            double s, gu[2] = {0, 0}, Hm[4] = {0, 0, 0, 0};
            if (kind == 0) {
                double dwb[2];
                double w = front ? border_weight(uv[0], uv[1], W, H, margin, dwb) : 0.0;
                if (!front) dwb[0] = dwb[1] = 0.0;
                if (front && in_image(&cam, uv)) cnt++;
                double G, dG[2], hG[3];
                Plane pl = plane_at(hm, half, files, (size_t)channels[m] * plane);
                bad |= bicubic(pl, W, H, uv[0], uv[1], &G, dG, hG);
                double Gc = mind(maxd(G, 0.0), 1.0);
                double rho = log1p_eps - log(Gc + eps);
                double w2 = w * w;
                s = lam * w2 * rho;
                if (with_jacobian) {
                    int live = G > 0.0 && G < 1.0;
                    double inv = live ? 1.0 / (Gc + eps) : 0.0;
                    double kk = 0.5 * lam * w2;
                    gu[0] = lam * w * rho * dwb[0] - kk * inv * dG[0];
                    gu[1] = lam * w * rho * dwb[1] - kk * inv * dG[1];
                    double a = kk * (inv * inv * dG[0] * dG[0] - inv * hG[0]);
                    double b = kk * (inv * inv * dG[0] * dG[1] - inv * hG[1]);
                    double c = kk * (inv * inv * dG[1] * dG[1] - inv * hG[2]);
                    psd2(a, b, c, Hm);
                    /* border fade, Gauss-Newton */
                    double br = lam * rho;
                    Hm[0] += br * dwb[0] * dwb[0];
                    Hm[1] += br * dwb[0] * dwb[1];
                    Hm[2] += br * dwb[1] * dwb[0];
                    Hm[3] += br * dwb[1] * dwb[1];
                }
            } else {
                int use = found[n * M + m] && front;
                double info = lam / (sigma * sigma);
                double e0 = use ? uv[0] - target[2 * (n * M + m)] : 0.0;
                double e1 = use ? uv[1] - target[2 * (n * M + m) + 1] : 0.0;
                if (use) cnt++;
                if (normal) {  /* distance along the search normal only */
                    double n0 = normal[2 * (n * M + m)], n1 = normal[2 * (n * M + m) + 1];
                    double dn = e0 * n0 + e1 * n1;
                    s = info * dn * dn;
                    gu[0] = info * dn * n0;
                    gu[1] = info * dn * n1;
                    double iu = use ? info : 0.0;
                    Hm[0] = iu * n0 * n0; Hm[1] = Hm[2] = iu * n0 * n1; Hm[3] = iu * n1 * n1;
                } else {
                    s = info * (e0 * e0 + e1 * e1);
                    gu[0] = info * e0;
                    gu[1] = info * e1;
                    Hm[0] = Hm[3] = use ? info : 0.0;
                }
            }
            double rho_s, drho;
            robust(rkind, rscale, s, &rho_s, &drho);
            c_n += 0.5 * rho_s;
            if (!with_jacobian) continue;
            if (rkind != 0) {
                gu[0] *= drho; gu[1] *= drho;
                for (int k = 0; k < 4; k++) Hm[k] *= drho;
            }
            if (gu[0] == 0.0 && gu[1] == 0.0 && Hm[0] == 0.0 && Hm[1] == 0.0 && Hm[3] == 0.0)
                continue;
            /* J (2 x 13) = Juv [ -R^T | [P]x | R^T Jp ] */
            double J[2][NCOL];
            for (int r = 0; r < 2; r++) {
                const double *a = Juv + 3 * r;
                /* a R^T: (a R^T)_k = sum_i a_i R[k][i] */
                double aRt[3];
                for (int k = 0; k < 3; k++)
                    aRt[k] = a[0] * R[3 * k] + a[1] * R[3 * k + 1] + a[2] * R[3 * k + 2];
                J[r][0] = -aRt[0]; J[r][1] = -aRt[1]; J[r][2] = -aRt[2];
                /* a [P]x = a x P (row vector times cross matrix) */
                J[r][3] = a[1] * P[2] - a[2] * P[1];
                J[r][4] = a[2] * P[0] - a[0] * P[2];
                J[r][5] = a[0] * P[1] - a[1] * P[0];
                for (int c = 0; c < 7; c++) {
                    double v = 0.0;
                    if (JA) {
                        for (int k = 0; k < 3; k++) {
                            double jp = (1.0 - f) * JA[(3 * m + k) * 7 + c]
                                        + f * JB[(3 * m + k) * 7 + c];
                            v += aRt[k] * jp;
                        }
                    }
                    J[r][6 + c] = v;
                }
            }
            double HJ[2][NCOL];
            for (int c = 0; c < NCOL; c++) {
                HJ[0][c] = Hm[0] * J[0][c] + Hm[1] * J[1][c];
                HJ[1][c] = Hm[2] * J[0][c] + Hm[3] * J[1][c];
                gacc[c] += J[0][c] * gu[0] + J[1][c] * gu[1];
            }
            for (int i = 0; i < NCOL; i++) {
                double j0 = J[0][i], j1 = J[1][i];
                double *row = acc + i * NCOL;
                for (int c = i; c < NCOL; c++) row[c] += j0 * HJ[0][c] + j1 * HJ[1][c];
            }
        }
        double *out = JtHJ ? JtHJ + n * NCOL * NCOL : NULL;
        if (with_jacobian && out) {
            for (int i = 0; i < NCOL; i++)
                for (int c = i; c < NCOL; c++) {
                    out[i * NCOL + c] += acc[i * NCOL + c];
                    if (c != i) out[c * NCOL + i] += acc[i * NCOL + c];
                }
            for (int c = 0; c < NCOL; c++) g[n * NCOL + c] += gacc[c];
        }
        cost[n] += c_n;
        count[n] += cnt;
        files_trim(files, hm);
        if (bad && n < first_bad) first_bad = n;
    }
    return first_bad == INT64_MAX ? -1 : first_bad;
}

/* ---- correspondence searches (costs/correspondence.py) ---------------------------- */

#define LOG_FLOOR 1e-6

/* Vertex of the parabola through the logs of three samples (correspondence._peak_offset). */
static double peak_offset(double vm, double v0, double vp) {
    double lm = log(maxd(vm, LOG_FLOOR)), l0 = log(maxd(v0, LOG_FLOOR));
    double lp = log(maxd(vp, LOG_FLOOR));
    double den = lm - 2.0 * l0 + lp;
    double off = den < -1e-12 ? 0.5 * (lm - lp) / den : 0.0;
    return mind(maxd(off, -0.5), 0.5);
}

/* Max over centre + offsets (du, dv pairs) inside the image and within radius R of the
 * window centre (cu0, cv0); -1 if none. Returns the (clamped) coordinates of the first max. */
static inline double window_max(Plane pl, int W, int H, int bu, int bv, const int64_t *off,
                         int64_t K, int cu0, int cv0, int64_t R, int *ou, int *ov, int *bad) {
    double best = -INFINITY;
    int best_u = 0, best_v = 0;
    for (int64_t k = 0; k < K; k++) {
        int cu = bu + (int)off[2 * k], cv = bv + (int)off[2 * k + 1];
        int du = cu - cu0, dv = cv - cv0;
        int ok = cu >= 0 && cu < W && cv >= 0 && cv < H && (int64_t)du * du + (int64_t)dv * dv <= R * R;
        int u = clampi(cu, 0, W - 1), v = clampi(cv, 0, H - 1);
        mark(pl, (size_t)v * W + u, (size_t)v * W + u);
        double val = at(pl, (size_t)v * W + u);
        if (!isfinite(val)) *bad = 1;
        if (!ok) val = -1.0;
        if (val > best) { best = val; best_u = u; best_v = v; }
    }
    *ou = best_u; *ov = best_v;
    return best;
}

/* Point correspondences: coarse offsets (K1, 2), fine offsets (K2, 2); the sub-pixel peak
 * from the neighbours `step` px away. uv (N, M, 2), usable (N, M). Writes target (N, M, 2),
 * found (N, M). Returns -1 or the first bad row. */
TF_EXPORT int64_t tf_point_search_scaled(
    int64_t N, int64_t M, int64_t width, int64_t height, const uint64_t *maps, int64_t half,
    const void *files, const int64_t *keyframes, const int64_t *channels, const double *uv,
    const uint8_t *usable,
    int64_t R, const int64_t *coarse, int64_t K1, const int64_t *fine, int64_t K2,
    int64_t step, double threshold, double *target, uint8_t *found) {
    const int W = (int)width, H = (int)height, s = (int)step;
    const size_t plane = (size_t)W * H;
    int64_t first_bad = INT64_MAX;
#pragma omp parallel for schedule(dynamic, 8) reduction(min : first_bad)
    for (int64_t n = 0; n < N; n++) {
        const uint64_t hm = maps[keyframes[n]];
        files_touch(files, hm);
        int bad = 0;
        for (int64_t m = 0; m < M; m++) {
            size_t i = (size_t)(n * M + m);
            Plane pl = plane_at(hm, half, files, (size_t)channels[m] * plane);
            int use = usable[i];
            int cu0 = (int)nearbyint(uv[2 * i]), cv0 = (int)nearbyint(uv[2 * i + 1]);
            int bu, bv, fu, fv;
            double peak;
            if (use) {
                window_max(pl, W, H, cu0, cv0, coarse, K1, cu0, cv0, R, &bu, &bv, &bad);
                peak = window_max(pl, W, H, bu, bv, fine, K2, cu0, cv0, R, &fu, &fv, &bad);
            } else {
                peak = -1.0;
                fu = clampi(cu0 + (int)coarse[0], 0, W - 1);
                fv = clampi(cv0 + (int)coarse[1], 0, H - 1);
            }
            int inner = fu >= s && fu <= W - 1 - s && fv >= s && fv <= H - 1 - s;
            found[i] = use && peak >= threshold && inner;
            const size_t i0 = (size_t)fv * W + clampi(fu - s, 0, W - 1);
            const size_t i1 = (size_t)fv * W + clampi(fu + s, 0, W - 1);
            const size_t i2 = (size_t)clampi(fv - s, 0, H - 1) * W + fu;
            const size_t i3 = (size_t)clampi(fv + s, 0, H - 1) * W + fu;
            mark(pl, i0, i1);
            mark(pl, i2, i2);
            mark(pl, i3, i3);
            double n0 = at(pl, i0), n1 = at(pl, i1), n2 = at(pl, i2), n3 = at(pl, i3);
            if (!(isfinite(n0) && isfinite(n1) && isfinite(n2) && isfinite(n3))) bad = 1;
            target[2 * i] = fu + s * peak_offset(n0, peak, n1);
            target[2 * i + 1] = fv + s * peak_offset(n2, peak, n3);
        }
        files_trim(files, hm);
        if (bad && n < first_bad) first_bad = n;
    }
    return first_bad == INT64_MAX ? -1 : first_bad;
}

/* Bilinear value at (pu, pv) of a plane; -1 outside the image or if !use. */
static inline double bilinear(Plane pl, int W, int H, double pu, double pv, int use, int *bad) {
    int ok = use && pu >= 0.0 && pu <= W - 1 && pv >= 0.0 && pv <= H - 1;
    int iu = clampi((int)floor(pu), 0, W - 2), iv = clampi((int)floor(pv), 0, H - 2);
    double fu = mind(maxd(pu - iu, 0.0), 1.0), fv = mind(maxd(pv - iv, 0.0), 1.0);
    const size_t r0 = (size_t)iv * W + iu;
    mark(pl, r0, r0 + 1);
    mark(pl, r0 + W, r0 + W + 1);
    double t00 = at(pl, r0), t01 = at(pl, r0 + 1), t10 = at(pl, r0 + W), t11 = at(pl, r0 + W + 1);
    if (!(isfinite(t00) && isfinite(t01) && isfinite(t10) && isfinite(t11))) *bad = 1;
    if (!ok) return -1.0;
    return (1 - fv) * ((1 - fu) * t00 + fu * t01) + fv * ((1 - fu) * t10 + fu * t11);
}

/* Line correspondences (correspondence.find_line_correspondences): coarse every 2 steps
 * over s = -L..L steps (a step is `step` px), then one step either side of the best.
 * Returns -1 or the first bad row. */
TF_EXPORT int64_t tf_line_search_scaled(
    int64_t N, int64_t M, int64_t width, int64_t height, const uint64_t *maps, int64_t half,
    const void *files, const int64_t *keyframes, const int64_t *channels, const double *uv,
    const double *normal,
    const uint8_t *usable, int64_t L, double step, double threshold, double *target,
    uint8_t *found) {
    const int W = (int)width, H = (int)height;
    const size_t plane = (size_t)W * H;
    const int64_t K = L + 1; /* coarse samples at -L, -L + 2, ..., L */
    int64_t first_bad = INT64_MAX;
#pragma omp parallel for schedule(dynamic, 8) reduction(min : first_bad)
    for (int64_t n = 0; n < N; n++) {
        const uint64_t hm = maps[keyframes[n]];
        files_touch(files, hm);
        int bad = 0;
        for (int64_t m = 0; m < M; m++) {
            size_t i = (size_t)(n * M + m);
            Plane pl = plane_at(hm, half, files, (size_t)channels[m] * plane);
            int use = usable[i];
            double u0 = uv[2 * i], v0 = uv[2 * i + 1];
            double nu = normal[2 * i], nv = normal[2 * i + 1];
            double best = -INFINITY, v_cm = -1.0, v_cp = -1.0, prev = -1.0;
            int64_t kc = 0;
            int after = 0;
            for (int64_t k = 0; k < K; k++) {
                double st = (double)(2 * k - L) * step;
                double val = bilinear(pl, W, H, u0 + st * nu, v0 + st * nv, use, &bad);
                if (after) { v_cp = val; after = 0; }
                if (val > best) { best = val; kc = k; v_cm = prev; after = 1; v_cp = -1.0; }
                prev = val;
            }
            double sc = (double)(2 * kc - L) * step;
            double fm = bilinear(pl, W, H, u0 + (sc - step) * nu, v0 + (sc - step) * nv, use, &bad);
            double fp = bilinear(pl, W, H, u0 + (sc + step) * nu, v0 + (sc + step) * nv, use, &bad);
            /* candidates at sc - step, sc, sc + step; first maximum */
            double peak = fm, vm = v_cm, vp = best, bs = sc - step;
            if (best > peak) { peak = best; vm = fm; vp = fp; bs = sc; }
            if (fp > peak) { peak = fp; vm = best; vp = v_cp; bs = sc + step; }
            int bracketed = bs > -L * step && bs < L * step && vm >= 0.0 && vp >= 0.0;
            found[i] = use && peak >= threshold && bracketed;
            double s = bs + step * peak_offset(vm, peak, vp);
            target[2 * i] = u0 + s * nu;
            target[2 * i + 1] = v0 + s * nv;
        }
        files_trim(files, hm);
        if (bad && n < first_bad) first_bad = n;
    }
    return first_bad == INT64_MAX ? -1 : first_bad;
}

/* ---- projection without derivatives (costs/projection.py) ------------------------ */

/* World points (M, 3), shared (stride 0) or per keyframe (stride M * 3), into N keyframes:
 * uv (N, M, 2), front (N, M), inside (N, M). */
TF_EXPORT void tf_project(int64_t N, int64_t M, const double *poses, const double *cam_par,
                          int64_t width, int64_t height, const double *pts, int64_t stride,
                          double *uv, uint8_t *front, uint8_t *inside) {
    Camera cam = camera_from(cam_par, (int)width, (int)height);
#pragma omp parallel for schedule(static)
    for (int64_t n = 0; n < N; n++) {
        double R[9];
        quat_to_R(poses + 7 * n, R);
        const double *t = poses + 7 * n + 4;
        const double *pn = pts + n * stride;
        for (int64_t m = 0; m < M; m++) {
            double d[3], P[3];
            for (int k = 0; k < 3; k++) d[k] = pn[3 * m + k] - t[k];
            for (int k = 0; k < 3; k++) P[k] = R[k] * d[0] + R[3 + k] * d[1] + R[6 + k] * d[2];
            size_t i = (size_t)(n * M + m);
            int f = project(&cam, P, uv + 2 * i, NULL);
            front[i] = (uint8_t)f;
            inside[i] = (uint8_t)(f && in_image(&cam, uv + 2 * i));
        }
    }
}

/* ---- block-tridiagonal solve (solver/linalg.py) ----------------------------------- */

/* In-place Cholesky of a 6x6 SPD matrix (lower factor). Returns 0 or 1 if not PD. */
static int chol6(double *a) {
    for (int j = 0; j < 6; j++) {
        double d = a[j * 6 + j];
        for (int k = 0; k < j; k++) d -= a[j * 6 + k] * a[j * 6 + k];
        if (!(d > 0.0) || !isfinite(d)) return 1;
        d = sqrt(d);
        a[j * 6 + j] = d;
        for (int i = j + 1; i < 6; i++) {
            double v = a[i * 6 + j];
            for (int k = 0; k < j; k++) v -= a[i * 6 + k] * a[j * 6 + k];
            a[i * 6 + j] = v / d;
        }
        for (int i = 0; i < j; i++) a[i * 6 + j] = 0.0;
    }
    return 0;
}

/* Solve L y = b (lower, 6x6) for m columns of b (6, m), in place. */
static void lsolve6(const double *L, double *b, int64_t m) {
    for (int i = 0; i < 6; i++)
        for (int64_t c = 0; c < m; c++) {
            double v = b[i * m + c];
            for (int k = 0; k < i; k++) v -= L[i * 6 + k] * b[k * m + c];
            b[i * m + c] = v / L[i * 6 + i];
        }
}

/* Solve L^T x = b in place. */
static void ltsolve6(const double *L, double *b, int64_t m) {
    for (int i = 5; i >= 0; i--)
        for (int64_t c = 0; c < m; c++) {
            double v = b[i * m + c];
            for (int k = i + 1; k < 6; k++) v -= L[k * 6 + i] * b[k * m + c];
            b[i * m + c] = v / L[i * 6 + i];
        }
}

/*
 * A x = b for symmetric block-tridiagonal A with 6x6 blocks: D (n, 6, 6) diagonal,
 * B (n-1, 6, 6) sub-diagonal (B[k] = A[k+1, k]), b (n, 6, m) overwritten by x.
 * work: (2 n, 6, 6) doubles. Returns 0, or k + 1 if the pivot block k is not PD.
 */
TF_EXPORT int64_t tf_block_tridiag_solve(int64_t n, int64_t m, const double *D,
                                         const double *B, double *b, double *work) {
    double *L = work;            /* n x 36: Cholesky factors of the pivots */
    double *C = work + 36 * n;   /* n-1 x 36: C_k = B_k L_k^-T */
    for (int64_t k = 0; k < n; k++) {
        double *Lk = L + 36 * k;
        memcpy(Lk, D + 36 * k, 36 * sizeof(double));
        if (k > 0) {
            const double *Cp = C + 36 * (k - 1);
            for (int i = 0; i < 6; i++)
                for (int j = 0; j < 6; j++) {
                    double v = 0.0;
                    for (int q = 0; q < 6; q++) v += Cp[i * 6 + q] * Cp[j * 6 + q];
                    Lk[i * 6 + j] -= v;
                }
            /* y_k = b_k - C_{k-1} y_{k-1} */
            double *bk = b + 6 * m * k;
            const double *bp = b + 6 * m * (k - 1);
            for (int i = 0; i < 6; i++)
                for (int64_t c = 0; c < m; c++) {
                    double v = 0.0;
                    for (int q = 0; q < 6; q++) v += Cp[i * 6 + q] * bp[q * m + c];
                    bk[i * m + c] -= v;
                }
        }
        if (chol6(Lk)) return k + 1;
        lsolve6(Lk, b + 6 * m * k, m);
        if (k + 1 < n) {
            /* C_k = B_k L_k^-T: solve L_k C_k^T = B_k^T, i.e. rows of C_k */
            double *Ck = C + 36 * k;
            const double *Bk = B + 36 * k;
            for (int i = 0; i < 6; i++)
                for (int j = 0; j < 6; j++) {
                    double v = Bk[i * 6 + j];
                    for (int q = 0; q < j; q++) v -= Ck[i * 6 + q] * Lk[j * 6 + q];
                    Ck[i * 6 + j] = v / Lk[j * 6 + j];
                }
        }
    }
    for (int64_t k = n - 1; k >= 0; k--) {
        double *bk = b + 6 * m * k;
        if (k + 1 < n) {
            const double *Ck = C + 36 * k;
            const double *xn = b + 6 * m * (k + 1);
            for (int i = 0; i < 6; i++)
                for (int64_t c = 0; c < m; c++) {
                    double v = 0.0;
                    for (int q = 0; q < 6; q++) v += Ck[q * 6 + i] * xn[q * m + c];
                    bk[i * m + c] -= v;
                }
        }
        ltsolve6(L + 36 * k, bk, m);
    }
    return 0;
}

/* Value check of heat-map arrays: the first of N keyframes (float32 arrays, or float16 if
 * `half`, of `count` values at the addresses `maps`) holding a value outside [lo, hi] or a
 * NaN, or N if none. One pass over the data on all threads (the caller names the file and
 * value). */
TF_EXPORT int64_t tf_first_out_of_range(int64_t N, const uint64_t *maps, int64_t half,
                                        int64_t count, double lo, double hi) {
    const ValueRange r = value_range(lo, hi, half);
    int64_t first_bad = INT64_MAX;
#pragma omp parallel for schedule(dynamic, 4) reduction(min : first_bad)
    for (int64_t n = 0; n < N; n++) {
        if (out_of_range((const void *)(uintptr_t)maps[n], half, count, &r) && n < first_bad)
            first_bad = n;
    }
    return first_bad == INT64_MAX ? N : first_bad;
}

/* How the files' values are checked: [lo, hi] as tf_first_out_of_range, the coarse grid of
 * HeatmapStack.coarse_grid kept in `grid` (n, channels, nrows, ncols values of the
 * storage: rows `rows` of each channel of H x W at every `step`-th column, ncols =
 * ceil(W / step)), and with `on_first_read` each keyframe checked when a kernel or
 * tf_files_read first reads it (the rest by tf_files_check). Returns 0, or ENOMEM. */
TF_EXPORT int64_t tf_files_check_setup(void *handle, double lo, double hi, int64_t H,
                                       int64_t W, const int64_t *rows, int64_t nrows,
                                       int64_t step, void *grid, int64_t on_first_read) {
    TfFiles *fl = (TfFiles *)handle;
    fl->range = value_range(lo, hi, fl->half);
    fl->height = H;
    fl->width = W;
    fl->nrows = nrows;
    fl->step = step;
    fl->ncols = (W + step - 1) / step;
    fl->channels = fl->count / (H * W);
    fl->rows = (int64_t *)malloc((size_t)(nrows > 0 ? nrows : 1) * sizeof(int64_t));
    if (fl->rows == NULL) return ENOMEM;
    memcpy(fl->rows, rows, (size_t)nrows * sizeof(int64_t));
    fl->grid = (char *)grid;
    fl->on_first_read = on_first_read;
    return 0;
}

/* Check every keyframe not checked yet, on all threads, each file's pages dropped once it
 * is checked (so that the process holds a few at a time). Returns the first keyframe of
 * all found holding a NaN or a value outside the range, or n if none. */
TF_EXPORT int64_t tf_files_check(void *handle) {
    TfFiles *fl = (TfFiles *)handle;
#pragma omp parallel for schedule(dynamic, 4)
    for (int64_t n = 0; n < fl->n; n++) {
        if (LOAD_U8(fl->checked + n)) continue;
        check_keyframe(fl, n);
        fl->dirty[n] = 0;
        files_drop(fl, n);
    }
    return LOAD_I64(&fl->first_bad);
}

/* The first keyframe found out of range so far, or n if none. */
TF_EXPORT int64_t tf_files_first_bad(const void *handle) {
    return LOAD_I64(&((const TfFiles *)handle)->first_bad);
}

/* Keyframe k's check: 0 not yet, 1 in range, 2 out of range. */
TF_EXPORT int64_t tf_files_checked(const void *handle, int64_t k) {
    return LOAD_U8(((const TfFiles *)handle)->checked + k);
}


TF_EXPORT int64_t tf_num_threads(void) {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

/* An (empty) importable module, so that the shared library is a regular extension that
 * setuptools builds and installs; the functions above are called through ctypes. */
static struct PyModuleDef kernels_module = {PyModuleDef_HEAD_INIT, "_kernels",
                                            "turbinefit's compiled kernels (see _native.py)",
                                            -1, NULL, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&kernels_module); }
