/*
 * stream_components.h - the frontier union-find of a streamed mesh's
 * components (stream_components.c), under the streamed clean-up and
 * --largest: each live vertex (an id at or above the last retire floor,
 * used by a triangle) has a slot (found through id_table.h) pointing to a
 * component record; a triangle joins its vertices' records (union by
 * size); a component's triangles may be held back, then passed on or
 * dropped; at a retire the vertices below the floor leave (their slots are
 * recycled once no held triangle uses them) and a record with no live
 * vertex left is a closed component.  Output: vertices numbered from 0 in
 * the order a passed triangle first uses them, delivered just before it
 * with the normal they came with; one retire() a stream's, the floor the
 * smallest output id of a vertex still live.  clean_stream.c and
 * largest_stream.c are its clients; nothing else includes this.
 */
#ifndef ISOMEND_STREAM_COMPONENTS_H
#define ISOMEND_STREAM_COMPONENTS_H

#include "id_table.h"
#include "isomend.h"

#include <stddef.h>
#include <stdint.h>

#define SC_NONE  UINT32_MAX
#define SC_NO_ID UINT64_MAX

typedef struct sc_slot {
    float p[3], n[3];
    uint64_t id;   /* the stream's id (SC_NO_ID: free)                 */
    uint64_t out;  /* the delivered id, SC_NO_ID before                */
    uint32_t comp; /* its component record while live (SC_NONE: none) */
    uint32_t refs; /* held triangles that use it                       */
} sc_slot;

/* A component record: a root (parent == itself) is a component, or a piece
 * of one still open. */
typedef struct sc_rec {
    uint32_t parent;
    uint32_t head, tail; /* its held triangles: a list through sc_held.next */
    uint32_t mark;       /* the retire epoch it was last found live in      */
    uint64_t triangles;  /* triangles so far (held or passed)               */
    uint64_t first;      /* its first triangle (stream order)               */
    uint64_t seed;       /* the client's (largest_stream.c's seed)          */
    int pass;            /* the client's: its triangles pass                */
    int used;
} sc_rec;

typedef struct sc_held {
    uint32_t s[3]; /* slots */
    uint32_t next;
    uint64_t seq; /* its place in the stream */
} sc_held;

/* The frontier, embedded in its client (zeroed, then sc_init()). */
typedef struct stream_components {
    isomend_mesh_sink out;
    int normals; /* the stream delivers normals */
    isomend_status status; /* the client's first failure, sticky (sc_fail) */

    uint64_t next_id, floor;
    uint64_t seq; /* the current triangle's place in the stream: the client
                   * counts it up after each triangle */
    sc_slot *slots;
    size_t nslots, cap_slots;
    uint32_t free_slot; /* a free list through slot.comp */
    id_table ids;       /* stream id -> slot              */
    uint32_t *live;     /* slots of ids >= floor, in id order */
    size_t nlive, cap_live;

    sc_rec *recs;
    size_t nrecs, cap_recs;
    uint32_t free_rec; /* through rec.parent */
    uint32_t epoch;

    sc_held *held;
    size_t nheld, cap_held;
    uint32_t free_held; /* through held.next */

    /* output */
    uint64_t triangles_out, out_next, out_floor;
    float *vpos, *vnrm;
    size_t nv_buf, cap_vbuf;
    uint64_t *tbuf;
    size_t nt_buf, cap_tbuf;
    sc_held *sortbuf;
    size_t cap_sort;
} stream_components;

/* Grows *p (elements of size bytes) to hold n; 0: out of memory. */
int sc_grow(void **p, size_t *cap, size_t n, size_t size);

void sc_init(stream_components *f, const isomend_mesh_sink *out);
/* The frontier from scratch (the stream played again), memory kept. */
void sc_restart(stream_components *f);
/* A client's memory estimate for a stream of desc and opts (0 if the
 * stream would be refused): the live vertices of a few slices, held_slices
 * slices of held triangles at bytes_per_held each, and `fixed` bytes. */
uint64_t sc_memory(const isomend_volume *desc, const isomend_options *opts, double held_slices,
                   double bytes_per_held, double fixed);
/* Records the first failure (st, once); returns the recorded one. */
isomend_status sc_fail(stream_components *f, isomend_status st);
void sc_free(stream_components *f);

/* The stream's vertices [first, first + count), live. */
isomend_status sc_vertices(stream_components *f, uint64_t first, size_t count, const float *pos,
                           const float *nrm);

/* Joining root `joined` into root `root`: the client's part of the records
 * (seed, pass); 0: refused. */
typedef int (*sc_merge_fn)(void *user, sc_rec *root, const sc_rec *joined);
/* Triangle ids (3 stream ids): its slots into s, its vertices' components
 * joined (merge, if not NULL, for each join) into *root, which counts it.
 * ISOMEND_ERR_INVALID_ARGUMENT: an id not live, or a merge refused. */
isomend_status sc_triangle(stream_components *f, const uint64_t *ids, uint32_t s[3], uint32_t *root,
                           sc_merge_fn merge, void *user);

/* Holds triangle t (slots) in root r, at place f->seq; 0: out of memory. */
int sc_hold(stream_components *f, uint32_t r, const uint32_t *t);
/* Frees root r's held triangles: appended to f->sortbuf[*n..] when pass,
 * else dropped; 0: out of memory. */
int sc_collect_held(stream_components *f, uint32_t r, int pass, size_t *n);
/* Emits f->sortbuf[0..n) in stream order; 0: out of memory. */
int sc_emit_sorted(stream_components *f, size_t n);
/* Root r's held triangles passed on in stream order (pass) or dropped. */
int sc_release_held(stream_components *f, uint32_t r, int pass);
/* Triangle t (slots) passes: its new vertices first; 0: out of memory. */
int sc_emit(stream_components *f, const uint32_t *t);
/* What passed since the last flush, to the sink; 0: the sink failed. */
int sc_flush(stream_components *f);

/* A closed component (root r, before its record is freed); 0: out of memory. */
typedef int (*sc_close_fn)(void *user, uint32_t r);
/* The retire: the live vertices below floor leave, the components without
 * a live vertex close (on_close for each); then, with output, what passed
 * goes to the sink and the output's floor rises, retire() on it when
 * forward.  ISOMEND_ERR_OUT_OF_MEMORY (close failed), ISOMEND_ERR_SINK. */
isomend_status sc_retire(stream_components *f, uint64_t floor, sc_close_fn on_close, void *user,
                         int output, int forward);

#endif
