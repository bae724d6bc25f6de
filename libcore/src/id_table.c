/*
 * id_table.c - the stream vertex id -> slot hash table (id_table.h).
 */
#include "id_table.h"

#include <stdlib.h>

static size_t hash_of(uint64_t id, size_t cap)
{
    id ^= id >> 33;
    id *= 0xff51afd7ed558ccdULL;
    id ^= id >> 33;
    return (size_t)id & (cap - 1);
}

int id_table_reserve(id_table *t)
{
    if (2 * (t->count + 1) <= t->cap)
        return 1;
    const size_t cap = t->cap ? 2 * t->cap : 1024;
    uint64_t *k = malloc(cap * sizeof *k);
    uint32_t *v = malloc(cap * sizeof *v);
    if (!k || !v) {
        free(k);
        free(v);
        return 0;
    }
    for (size_t i = 0; i < cap; i++)
        k[i] = ID_TABLE_FREE;
    for (size_t i = 0; i < t->cap; i++)
        if (t->key[i] != ID_TABLE_FREE) {
            size_t h = hash_of(t->key[i], cap);
            while (k[h] != ID_TABLE_FREE)
                h = (h + 1) & (cap - 1);
            k[h] = t->key[i];
            v[h] = t->val[i];
        }
    free(t->key);
    free(t->val);
    t->key = k;
    t->val = v;
    t->cap = cap;
    return 1;
}

uint32_t id_table_find(const id_table *t, uint64_t id)
{
    if (!t->cap)
        return ID_TABLE_NONE;
    for (size_t h = hash_of(id, t->cap);; h = (h + 1) & (t->cap - 1)) {
        if (t->key[h] == id)
            return t->val[h];
        if (t->key[h] == ID_TABLE_FREE)
            return ID_TABLE_NONE;
    }
}

void id_table_insert(id_table *t, uint64_t id, uint32_t slot)
{
    size_t h = hash_of(id, t->cap);
    while (t->key[h] != ID_TABLE_FREE)
        h = (h + 1) & (t->cap - 1);
    t->key[h] = id;
    t->val[h] = slot;
    t->count++;
}

void id_table_remove(id_table *t, uint64_t id)
{
    const size_t mask = t->cap - 1;
    size_t h = hash_of(id, t->cap);
    while (t->key[h] != id)
        h = (h + 1) & mask;
    /* backward shift: the entries after the hole that may move into it */
    for (size_t j = (h + 1) & mask;; j = (j + 1) & mask) {
        if (t->key[j] == ID_TABLE_FREE)
            break;
        const size_t home = hash_of(t->key[j], t->cap);
        /* j's entry may fill h if its home is not in (h, j] cyclically */
        if (((j - home) & mask) >= ((j - h) & mask)) {
            t->key[h] = t->key[j];
            t->val[h] = t->val[j];
            h = j;
        }
    }
    t->key[h] = ID_TABLE_FREE;
    t->count--;
}

void id_table_clear(id_table *t)
{
    for (size_t i = 0; i < t->cap; i++)
        t->key[i] = ID_TABLE_FREE;
    t->count = 0;
}

void id_table_free(id_table *t)
{
    free(t->key);
    free(t->val);
    *t = (id_table){0};
}
