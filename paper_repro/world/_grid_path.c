/* The guide's shortest path on its 26-connected grid (paper_repro.world.guide.Guide._plan).
 *
 * A* from several start cells, each entering at its own cost (the vehicle's distance to the
 * cell's centre), to one goal cell, through free cells only. An edge to one of the 26
 * neighbours costs the length the caller gives for its offset (a metre up or down weighs
 * `climb`). The heuristic is the straight-line length under the same weights,
 * cell·√(Δi² + Δj² + (climb·Δk)²): every edge costs exactly that length of its own offset,
 * so the heuristic is consistent (the triangle inequality) and the first time the goal
 * leaves the queue its cost is the least over every start. It is scaled by 1 − 1e-12 so that
 * rounding never makes it exceed the true cost; a cell whose cost improves after it was
 * expanded is queued again, so the result stays exact in any case.
 *
 * Ties in the queue go to the entry with the larger cost so far (the deeper one), then to
 * the lower cell number: the search is deterministic.
 *
 * Built with -ffp-contract=off, like the map: every sum is rounded as written.
 */

#include <math.h>
#include <stdint.h>
#include <stdlib.h>

typedef struct {
    double f, g;  /* cost so far plus heuristic, and cost so far */
    int64_t node;
} Entry;

typedef struct {
    Entry *items;
    int64_t size, cap;
} Heap;

static int before(const Entry *a, const Entry *b) {
    if (a->f != b->f) return a->f < b->f;
    if (a->g != b->g) return a->g > b->g;
    return a->node < b->node;
}

static int push(Heap *h, double f, double g, int64_t node) {
    if (h->size == h->cap) {
        int64_t cap = h->cap ? 2 * h->cap : 1024;
        Entry *items = realloc(h->items, (size_t)cap * sizeof(Entry));
        if (!items) return -1;
        h->items = items;
        h->cap = cap;
    }
    int64_t i = h->size++;
    Entry e = {f, g, node};
    while (i > 0) {
        int64_t parent = (i - 1) / 2;
        if (!before(&e, &h->items[parent])) break;
        h->items[i] = h->items[parent];
        i = parent;
    }
    h->items[i] = e;
    return 0;
}

static Entry pop(Heap *h) {
    Entry top = h->items[0], last = h->items[--h->size];
    int64_t i = 0;
    for (;;) {
        int64_t child = 2 * i + 1;
        if (child >= h->size) break;
        if (child + 1 < h->size && before(&h->items[child + 1], &h->items[child])) child++;
        if (!before(&h->items[child], &last)) break;
        h->items[i] = h->items[child];
        i = child;
    }
    if (h->size) h->items[i] = last;
    return top;
}

/* shape: (3,) cells per axis; offsets: (26, 3) neighbour offsets; steps: (26,) their
 * lengths, m; blocked: (n,) 1 for a blocked cell; sources, gaps: (n_sources,) free start
 * cells and their entry costs, m; goal: the free goal cell; cell, climb: for the heuristic.
 * Writes the path's cells, start first and goal last, to chain (room for n) and each one's
 * length to the goal along the path to along (m). Returns the number of cells on the path,
 * 0 when the goal cannot be reached, -1 when memory is short. */
int64_t grid_path(const int64_t *shape, const int64_t *offsets, const double *steps,
                  const uint8_t *blocked, int64_t n_sources, const int64_t *sources,
                  const double *gaps, int64_t goal, double cell, double climb,
                  int64_t *chain, double *along) {
    const int64_t nx = shape[0], ny = shape[1], nz = shape[2], n = nx * ny * nz;
    const int64_t gi = goal / (ny * nz), gj = (goal / nz) % ny, gk = goal % nz;
    const double scale = cell * (1.0 - 1e-12);
    double *g = malloc((size_t)n * sizeof(double));
    int64_t *parent = malloc((size_t)n * sizeof(int64_t));
    Heap heap = {NULL, 0, 0};
    int64_t found = 0;
    if (!g || !parent) goto fail;
    for (int64_t v = 0; v < n; v++) g[v] = INFINITY;
    for (int64_t s = 0; s < n_sources; s++) {
        int64_t v = sources[s];
        if (gaps[s] < g[v]) {
            g[v] = gaps[s];
            parent[v] = -1;
            double di = (double)(v / (ny * nz) - gi), dj = (double)((v / nz) % ny - gj),
                   dk = climb * (double)(v % nz - gk);
            if (push(&heap, g[v] + scale * sqrt(di * di + dj * dj + dk * dk), g[v], v)) goto fail;
        }
    }
    while (heap.size) {
        Entry e = pop(&heap);
        if (e.g > g[e.node]) continue;  /* a stale entry: the cell was reached cheaper */
        if (e.node == goal) {
            found = 1;
            break;
        }
        int64_t i = e.node / (ny * nz), j = (e.node / nz) % ny, k = e.node % nz;
        for (int d = 0; d < 26; d++) {
            int64_t a = i + offsets[3 * d], b = j + offsets[3 * d + 1],
                    c = k + offsets[3 * d + 2];
            if (a < 0 || a >= nx || b < 0 || b >= ny || c < 0 || c >= nz) continue;
            int64_t v = (a * ny + b) * nz + c;
            if (blocked[v]) continue;
            double cost = e.g + steps[d];
            if (cost < g[v]) {
                g[v] = cost;
                parent[v] = e.node;
                double di = (double)(a - gi), dj = (double)(b - gj), dk = climb * (double)(c - gk);
                if (push(&heap, cost + scale * sqrt(di * di + dj * dj + dk * dk), cost, v))
                    goto fail;
            }
        }
    }
    int64_t m = 0;
    if (found) {
        for (int64_t v = goal; v >= 0; v = parent[v]) chain[m++] = v;
        for (int64_t a = 0, b = m - 1; a < b; a++, b--) {  /* start first */
            int64_t t = chain[a];
            chain[a] = chain[b];
            chain[b] = t;
        }
        double length[27] = {0};  /* the step lengths, by (Δi + 1)·9 + (Δj + 1)·3 + Δk + 1 */
        for (int d = 0; d < 26; d++)
            length[(offsets[3 * d] + 1) * 9 + (offsets[3 * d + 1] + 1) * 3 + offsets[3 * d + 2] + 1] =
                steps[d];
        along[m - 1] = 0.0;
        for (int64_t p = m - 2; p >= 0; p--) {
            int64_t u = chain[p], v = chain[p + 1];
            int64_t di = v / (ny * nz) - u / (ny * nz), dj = (v / nz) % ny - (u / nz) % ny,
                    dk = v % nz - u % nz;
            along[p] = along[p + 1] + length[(di + 1) * 9 + (dj + 1) * 3 + dk + 1];
        }
    }
    free(g);
    free(parent);
    free(heap.items);
    return m;
fail:
    free(g);
    free(parent);
    free(heap.items);
    return -1;
}
