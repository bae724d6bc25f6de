/*
 * id_table.h - a stream vertex id -> slot hash table (id_table.c): open
 * addressing with linear probing, removal by backward shift.  The streamed
 * post-processing keeps its vertices in slots found through one
 * (stream_window.c, stream_components.c); nothing else includes this.
 */
#ifndef ISOMEND_ID_TABLE_H
#define ISOMEND_ID_TABLE_H

#include <stddef.h>
#include <stdint.h>

#define ID_TABLE_NONE UINT32_MAX /* no slot                 */
#define ID_TABLE_FREE UINT64_MAX /* an empty entry's key    */

/* Zeroed: an empty table (nothing allocated until the first reserve). */
typedef struct id_table {
    uint64_t *key; /* ID_TABLE_FREE: an empty entry */
    uint32_t *val;
    size_t cap, count; /* cap: a power of 2, or 0 */
} id_table;

/* Room for one more id (the table at most half full); 0: out of memory. */
int id_table_reserve(id_table *t);
/* The slot of id, or ID_TABLE_NONE. */
uint32_t id_table_find(const id_table *t, uint64_t id);
/* Adds id -> slot: id is not in t, and id_table_reserve() made room. */
void id_table_insert(id_table *t, uint64_t id, uint32_t slot);
/* Removes id, which is in t. */
void id_table_remove(id_table *t, uint64_t id);
/* Empties t, keeping its memory. */
void id_table_clear(id_table *t);
void id_table_free(id_table *t);

#endif
