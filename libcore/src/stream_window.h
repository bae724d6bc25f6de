/*
 * stream_window.h - the sliding window of the streamed post-processing
 * (stream_window.c): a stream's mesh in chunks of K layers, each window
 * (the band held from the previous one + a chunk) handed to a client that
 * processes it as one mesh, the band at the new top plane held back, the
 * rest final and delivered.  decimate_stream.c and smooth_stream.c are its
 * clients; nothing else includes this.
 */
#ifndef ISOMEND_STREAM_WINDOW_H
#define ISOMEND_STREAM_WINDOW_H

#include "isomend.h"
#include "mem_tally.h"

#include <stddef.h>
#include <stdint.h>

typedef struct stream_window stream_window;

/* The most rings a held band has (stream_window_client.band + .more). */
#define STREAM_WINDOW_MAX_RINGS 64

/* A window as its client gets it: the held triangles and the chunk's as one
 * mesh, each vertex at its slot's position, vertices in the order of first
 * use; vertices are slots (a stream vertex has one while a held, waiting or
 * window triangle uses it). */
typedef struct stream_window_mesh {
    const isomend_mesh *m; /* the held triangles (m's first nheld), then the chunk's */
    const uint32_t *slot;  /* m's vertex v is slot slot[v]                            */
    size_t nheld;
    const uint64_t *chunk; /* the chunk's triangles, the stream's ids (3 each)        */
    size_t nchunk;
    uint64_t top_lo, top_hi; /* the top plane: stream ids [top_lo, top_hi), held      */
} stream_window_mesh;

/* What a client does with a window and the window's settings for it.  The
 * hooks get `user` and the window; `data` is the client's own bytes of a
 * slot (stream_window_data). */
typedef struct stream_window_client {
    void *user;
    size_t data_bytes; /* the client's bytes a slot, zeroed when a slot is made        */
    uint32_t band;     /* the held band: triangles within this many rings of the top plane */
    uint32_t more;     /* and up to this many rings more (band + more at most
                        * STREAM_WINDOW_MAX_RINGS), of the triangles whose vertices were all
                        * made within `young` layers of the top plane, while those add at
                        * most a layer's worth of the chunk's triangles (its triangles / K):
                        * none for chunks of 1 layer; 0: none                               */
    uint32_t young;
    int retire_each;   /* 1: one retire() for each of the stream's (the lowest id a waiting
                        * triangle uses), none at the end; 0: a retire() when that floor
                        * rises, and one for everything at the end                      */
    int strict_floor;  /* 1: a triangle on an id below the stream's last floor is refused */
    /* A slot made for stream vertex at p (NULL: nothing to do). */
    void (*made)(void *user, void *data, const float *p);
    /* Processes window w: *r its result (NULL for an empty window), *kept
     * r's vertex v is w's vertex kept[v] (NULL: the same vertices);
     * malloc'ed, the window frees them.  Called for every window, empty too. */
    isomend_status (*process)(void *user, stream_window *sw, const stream_window_mesh *w,
                              isomend_mesh **r, uint32_t **kept);
    /* r's vertex v is slot slot[v], fin[t]: r's triangle t is final (the
     * others held): the client moves the slots where r has them
     * (stream_window_pos) before the final triangles count. */
    void (*settle)(void *user, stream_window *sw, const isomend_mesh *r, const uint32_t *slot,
                   const uint8_t *fin);
    /* Triangle t (slots) is final, counted for its vertices' normals; 0:
     * out of memory (NULL: nothing to do). */
    int (*final)(void *user, stream_window *sw, const uint32_t *t);
    /* Slot s is delivered, at its position (NULL: nothing to do). */
    void (*delivered)(void *user, stream_window *sw, uint32_t s);
    /* After a window's delivery, before the stream's positions below its
     * top plane are dropped (NULL: nothing to do). */
    isomend_status (*done)(void *user, stream_window *sw);
} stream_window_client;

/* The counts so far. */
typedef struct stream_window_counts {
    uint64_t vertices_in, triangles_in;   /* the stream's                      */
    uint64_t final_triangles;             /* made final                        */
    uint64_t vertices_out, triangles_out; /* delivered                         */
} stream_window_counts;

/* A window of K layers between a stream and `out` (normals: with the final
 * triangles' area-weighted normals); `client` is copied. */
isomend_status stream_window_begin(const stream_window_client *client, const isomend_mesh_sink *out,
                                   int normals, int64_t K, stream_window **sw);
/* The sink the stream feeds. */
void stream_window_sink(stream_window *sw, isomend_mesh_sink *sink);
/* The last window, if anything is left or `force` (no chunk follows: the
 * whole band final); the stream's status. */
isomend_status stream_window_finish(stream_window *sw, int force);
/* After the last window: nothing is left waiting; the last retire(); the
 * stream's status. */
isomend_status stream_window_close(stream_window *sw);
void stream_window_destroy(stream_window *sw);

/* The first failure is the stream's status (returned). */
isomend_status stream_window_fail(stream_window *sw, isomend_status st);
isomend_status stream_window_status(const stream_window *sw);
stream_window_counts stream_window_counts_of(const stream_window *sw);
/* Slot s's position (final once a final triangle has it) and client bytes. */
float *stream_window_pos(stream_window *sw, uint32_t s);
void *stream_window_data(stream_window *sw, uint32_t s);
/* The stream's position of vertex id, delivered and not below the last
 * window's top plane (a window's `done` still has its chunk's: the ids
 * below its top plane are dropped after it). */
const float *stream_window_raw(const stream_window *sw, uint64_t id);
/* The held triangles (slots, 3 each) and their count. */
const uint32_t *stream_window_held(const stream_window *sw, size_t *count);
/* What the window and its client hold (mem_tally.h): the window counts its
 * own arrays, its scratch and a window's result (the mesh and `kept`); the
 * client counts its own bytes in it, and its work on a window (process) as a
 * spike.  The most held at once so far. */
mem_tally *stream_window_tally(stream_window *sw);
uint64_t stream_window_peak_bytes(const stream_window *sw);
/* The bytes of a mesh's arrays (positions, normals, triangles, origins,
 * slices) and its struct, as a window's result holds them; 0 for NULL. */
uint64_t stream_window_mesh_bytes(const isomend_mesh *m);

#endif
