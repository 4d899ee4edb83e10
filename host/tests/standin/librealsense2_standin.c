/* A stand-in for the subset of the librealsense2 C API that riseg's RealSense driver
 * calls (host/src/rig/realsense/ffi.rs), built by host/tests/realsense_standin.rs into a
 * shared library the driver loads through RISEG_REALSENSE_LIB.
 *
 * The enums below are copied in order from librealsense2 v2.56.5 (rs_sensor.h, rs_types.h)
 * so their values come from the C compiler, not from the driver's Rust constants: a wrong
 * constant in the driver is refused here. The signatures are those of the same headers.
 *
 * Frames are synthetic with known content (see colour_at, depth_at). Unaligned depth is
 * offset by ALIGN_OFFSET, which only the align block to RS2_STREAM_COLOR removes; the
 * hole-filling block fills zero depth with HOLE_FILL.
 *
 * Build-time knobs: -DSTANDIN_DEVICES=n (devices connected, default 1),
 * -DSTANDIN_FAIL_AFTER=n (rs2_pipeline_wait_for_frames fails after n framesets: the camera
 * is unplugged; default never).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef STANDIN_DEVICES
#define STANDIN_DEVICES 1
#endif
#ifndef STANDIN_FAIL_AFTER
#define STANDIN_FAIL_AFTER -1
#endif
#define ALIGN_OFFSET 10000
#define HOLE_FILL 4242

typedef enum rs2_stream {
    RS2_STREAM_ANY, RS2_STREAM_DEPTH, RS2_STREAM_COLOR, RS2_STREAM_INFRARED, RS2_STREAM_FISHEYE,
    RS2_STREAM_GYRO, RS2_STREAM_ACCEL, RS2_STREAM_GPIO, RS2_STREAM_POSE, RS2_STREAM_CONFIDENCE,
    RS2_STREAM_MOTION, RS2_STREAM_COUNT
} rs2_stream;
typedef enum rs2_format {
    RS2_FORMAT_ANY, RS2_FORMAT_Z16, RS2_FORMAT_DISPARITY16, RS2_FORMAT_XYZ32F, RS2_FORMAT_YUYV,
    RS2_FORMAT_RGB8, RS2_FORMAT_BGR8
} rs2_format;
typedef enum rs2_distortion {
    RS2_DISTORTION_NONE, RS2_DISTORTION_MODIFIED_BROWN_CONRADY, RS2_DISTORTION_INVERSE_BROWN_CONRADY,
    RS2_DISTORTION_FTHETA, RS2_DISTORTION_BROWN_CONRADY, RS2_DISTORTION_KANNALA_BRANDT4
} rs2_distortion;
typedef struct rs2_intrinsics {
    int width, height;
    float ppx, ppy, fx, fy;
    rs2_distortion model;
    float coeffs[5];
} rs2_intrinsics;

typedef struct rs2_error { char message[256]; const char *function; } rs2_error;
typedef struct rs2_context { int api_version; } rs2_context;
typedef struct rs2_device_list { int count; } rs2_device_list;
typedef struct rs2_config { int w[2], h[2], fps[2], enabled[2]; } rs2_config;
typedef struct rs2_pipeline { rs2_config conf; int started; } rs2_pipeline;
typedef struct rs2_pipeline_profile { int unused; } rs2_pipeline_profile;
typedef struct rs2_stream_profile { rs2_stream stream; rs2_format format; int fps; int w, h; } rs2_stream_profile;
typedef struct rs2_frame {
    int refs;
    struct rs2_frame *parts[2]; /* frameset: colour, depth */
    rs2_stream_profile *profile;
    int w, h, stride;
    int aligned;
    unsigned char *data;
} rs2_frame;
typedef struct rs2_frame_queue { rs2_frame *slot; } rs2_frame_queue;
typedef enum { BLOCK_ALIGN, BLOCK_SPATIAL, BLOCK_TEMPORAL, BLOCK_HOLES } block_kind;
typedef struct rs2_processing_block { block_kind kind; rs2_frame_queue *queue; } rs2_processing_block;

static rs2_stream_profile colour_profile, depth_profile;
static int framesets;

static void fail(rs2_error **error, const char *function, const char *message) {
    if (!error) return;
    rs2_error *e = calloc(1, sizeof *e);
    snprintf(e->message, sizeof e->message, "%s", message);
    e->function = function;
    *error = e;
}
const char *rs2_get_error_message(const rs2_error *e) { return e->message; }
const char *rs2_get_failed_function(const rs2_error *e) { return e->function; }
void rs2_free_error(rs2_error *e) { free(e); }

rs2_context *rs2_create_context(int api_version, rs2_error **error) {
    /* librealsense's rule: same major, runtime minor >= the caller's. */
    if (api_version / 10000 != 2 || (api_version / 100) % 100 > 56) {
        fail(error, "rs2_create_context", "API version mismatch");
        return NULL;
    }
    rs2_context *c = calloc(1, sizeof *c);
    c->api_version = api_version;
    return c;
}
void rs2_delete_context(rs2_context *c) { free(c); }
rs2_device_list *rs2_query_devices(const rs2_context *c, rs2_error **error) {
    (void)c; (void)error;
    rs2_device_list *l = calloc(1, sizeof *l);
    l->count = STANDIN_DEVICES;
    return l;
}
int rs2_get_device_count(const rs2_device_list *l, rs2_error **error) { (void)error; return l->count; }
void rs2_delete_device_list(rs2_device_list *l) { free(l); }

rs2_config *rs2_create_config(rs2_error **error) { (void)error; return calloc(1, sizeof(rs2_config)); }
void rs2_delete_config(rs2_config *c) { free(c); }
void rs2_config_enable_stream(rs2_config *c, rs2_stream stream, int index, int width, int height,
                              rs2_format format, int framerate, rs2_error **error) {
    int i;
    if (stream == RS2_STREAM_COLOR && format == RS2_FORMAT_RGB8) i = 0;
    else if (stream == RS2_STREAM_DEPTH && format == RS2_FORMAT_Z16) i = 1;
    else { fail(error, "rs2_config_enable_stream", "unsupported stream and format"); return; }
    if (index != -1 && index != 0) { fail(error, "rs2_config_enable_stream", "bad index"); return; }
    c->w[i] = width; c->h[i] = height; c->fps[i] = framerate; c->enabled[i] = 1;
}

rs2_pipeline *rs2_create_pipeline(rs2_context *ctx, rs2_error **error) {
    (void)ctx; (void)error;
    return calloc(1, sizeof(rs2_pipeline));
}
void rs2_delete_pipeline(rs2_pipeline *p) { free(p); }
rs2_pipeline_profile *rs2_pipeline_start_with_config(rs2_pipeline *p, rs2_config *c, rs2_error **error) {
    if (!c->enabled[0] || !c->enabled[1]) {
        fail(error, "rs2_pipeline_start_with_config", "colour and depth must both be enabled");
        return NULL;
    }
    p->conf = *c;
    p->started = 1;
    colour_profile = (rs2_stream_profile){RS2_STREAM_COLOR, RS2_FORMAT_RGB8, c->fps[0], c->w[0], c->h[0]};
    depth_profile = (rs2_stream_profile){RS2_STREAM_DEPTH, RS2_FORMAT_Z16, c->fps[1], c->w[1], c->h[1]};
    return calloc(1, sizeof(rs2_pipeline_profile));
}
void rs2_delete_pipeline_profile(rs2_pipeline_profile *p) { free(p); }
void rs2_pipeline_stop(rs2_pipeline *p, rs2_error **error) {
    if (!p->started) fail(error, "rs2_pipeline_stop", "not started");
    p->started = 0;
}

/* Frame content: known functions of the pixel and the frameset number k (from 1). */
static unsigned char colour_at(int x, int y, int k, int c) {
    return (unsigned char)(c == 0 ? x + k : c == 1 ? y : x * y + 7 * k);
}
static unsigned short depth_at(int x, int y, int k) {
    return x == 1 ? 0 : (unsigned short)(300 + x + 2 * y + k);
}

static rs2_frame *new_frame(rs2_stream_profile *profile, int bytes_per_px, int k) {
    rs2_frame *f = calloc(1, sizeof *f);
    f->refs = 1;
    f->profile = profile;
    f->w = profile->w; f->h = profile->h;
    f->stride = f->w * bytes_per_px + 6; /* padded rows */
    f->data = malloc((size_t)f->stride * f->h);
    memset(f->data, 0xEE, (size_t)f->stride * f->h);
    for (int y = 0; y < f->h; y++)
        for (int x = 0; x < f->w; x++) {
            unsigned char *p = f->data + y * f->stride + x * bytes_per_px;
            if (bytes_per_px == 3) {
                for (int c = 0; c < 3; c++) p[c] = colour_at(x, y, k, c);
            } else {
                unsigned short d = depth_at(x, y, k);
                if (d) d += ALIGN_OFFSET;
                memcpy(p, &d, 2);
            }
        }
    return f;
}

rs2_frame *rs2_pipeline_wait_for_frames(rs2_pipeline *p, unsigned int timeout_ms, rs2_error **error) {
    (void)timeout_ms;
    if (!p->started) { fail(error, "rs2_pipeline_wait_for_frames", "pipeline not started"); return NULL; }
    if (STANDIN_FAIL_AFTER >= 0 && framesets >= STANDIN_FAIL_AFTER) {
        fail(error, "rs2_pipeline_wait_for_frames", "Frame didn't arrive within 5000");
        return NULL;
    }
    framesets++;
    rs2_frame *set = calloc(1, sizeof *set);
    set->refs = 1;
    set->parts[0] = new_frame(&colour_profile, 3, framesets);
    set->parts[1] = new_frame(&depth_profile, 2, framesets);
    return set;
}

void rs2_release_frame(rs2_frame *f) {
    if (!f || --f->refs > 0) return;
    for (int i = 0; i < 2; i++) rs2_release_frame(f->parts[i]);
    free(f->data);
    free(f);
}
int rs2_embedded_frames_count(rs2_frame *f, rs2_error **error) {
    if (!f->parts[0]) { fail(error, "rs2_embedded_frames_count", "not a frameset"); return 0; }
    return 2;
}
rs2_frame *rs2_extract_frame(rs2_frame *f, int index, rs2_error **error) {
    if (!f->parts[0] || index < 0 || index > 1) { fail(error, "rs2_extract_frame", "bad index"); return NULL; }
    f->parts[index]->refs++;
    return f->parts[index];
}
const void *rs2_get_frame_data(const rs2_frame *f, rs2_error **error) { (void)error; return f->data; }
int rs2_get_frame_width(const rs2_frame *f, rs2_error **error) { (void)error; return f->w; }
int rs2_get_frame_height(const rs2_frame *f, rs2_error **error) { (void)error; return f->h; }
int rs2_get_frame_stride_in_bytes(const rs2_frame *f, rs2_error **error) { (void)error; return f->stride; }
float rs2_depth_frame_get_units(const rs2_frame *f, rs2_error **error) {
    if (f->profile != &depth_profile) { fail(error, "rs2_depth_frame_get_units", "not a depth frame"); return 0; }
    return 0.001f;
}
const rs2_stream_profile *rs2_get_frame_stream_profile(const rs2_frame *f, rs2_error **error) {
    (void)error;
    return f->profile;
}
void rs2_get_stream_profile_data(const rs2_stream_profile *m, rs2_stream *stream, rs2_format *format,
                                 int *index, int *unique_id, int *framerate, rs2_error **error) {
    (void)error;
    *stream = m->stream; *format = m->format; *index = 0; *unique_id = m->stream; *framerate = m->fps;
}
void rs2_get_video_stream_intrinsics(const rs2_stream_profile *m, rs2_intrinsics *i, rs2_error **error) {
    if (m != &colour_profile) { fail(error, "rs2_get_video_stream_intrinsics", "asked of depth"); return; }
    memset(i, 0, sizeof *i);
    i->width = m->w; i->height = m->h;
    i->ppx = 0.5f * m->w - 0.375f; i->ppy = 0.5f * m->h + 0.125f;
    i->fx = 615.5f; i->fy = 616.25f;
    i->model = RS2_DISTORTION_INVERSE_BROWN_CONRADY;
}

static rs2_processing_block *new_block(block_kind kind) {
    rs2_processing_block *b = calloc(1, sizeof *b);
    b->kind = kind;
    return b;
}
rs2_processing_block *rs2_create_align(rs2_stream align_to, rs2_error **error) {
    if (align_to != RS2_STREAM_COLOR) { fail(error, "rs2_create_align", "stand-in aligns to colour only"); return NULL; }
    return new_block(BLOCK_ALIGN);
}
rs2_processing_block *rs2_create_spatial_filter_block(rs2_error **error) { (void)error; return new_block(BLOCK_SPATIAL); }
rs2_processing_block *rs2_create_temporal_filter_block(rs2_error **error) { (void)error; return new_block(BLOCK_TEMPORAL); }
rs2_processing_block *rs2_create_hole_filling_filter_block(rs2_error **error) { (void)error; return new_block(BLOCK_HOLES); }
void rs2_delete_processing_block(rs2_processing_block *b) { free(b); }
rs2_frame_queue *rs2_create_frame_queue(int capacity, rs2_error **error) {
    if (capacity < 1) { fail(error, "rs2_create_frame_queue", "capacity < 1"); return NULL; }
    return calloc(1, sizeof(rs2_frame_queue));
}
void rs2_delete_frame_queue(rs2_frame_queue *q) { if (q->slot) rs2_release_frame(q->slot); free(q); }
void rs2_start_processing_queue(rs2_processing_block *b, rs2_frame_queue *q, rs2_error **error) {
    (void)error;
    b->queue = q;
}
void rs2_process_frame(rs2_processing_block *b, rs2_frame *f, rs2_error **error) {
    if (!b->queue) { fail(error, "rs2_process_frame", "no queue started"); rs2_release_frame(f); return; }
    rs2_frame *d = f->parts[1];
    for (int y = 0; y < d->h; y++)
        for (int x = 0; x < d->w; x++) {
            unsigned short v;
            memcpy(&v, d->data + y * d->stride + 2 * x, 2);
            if (b->kind == BLOCK_ALIGN && v) v -= ALIGN_OFFSET;
            if (b->kind == BLOCK_HOLES && !v) v = HOLE_FILL + (f->aligned ? 0 : ALIGN_OFFSET);
            memcpy(d->data + y * d->stride + 2 * x, &v, 2);
        }
    if (b->kind == BLOCK_ALIGN) f->aligned = 1;
    if (b->queue->slot) rs2_release_frame(b->queue->slot);
    b->queue->slot = f; /* ownership passes to the queue */
}
rs2_frame *rs2_wait_for_frame(rs2_frame_queue *q, unsigned int timeout_ms, rs2_error **error) {
    (void)timeout_ms;
    rs2_frame *f = q->slot;
    if (!f) { fail(error, "rs2_wait_for_frame", "Frame did not arrive in time"); return NULL; }
    q->slot = NULL;
    return f;
}
