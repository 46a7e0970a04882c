/* One scan into the local voxel map (paper_repro.world.local_map.VoxelMap.update).
 *
 * The map is a set of voxels sorted by their packed index (key), held in arrays the caller
 * owns, with room for `cap` voxels: the update may add one voxel per return and then drops
 * the forgotten ones, keeping the order. Every step follows the docstring of VoxelMap, in the
 * order it states: association, misses, new voxels, hits, the representative mean, the
 * occupancy state with its hysteresis, forgetting. Built with -ffp-contract=off, so that each
 * product and sum is rounded as written (the mean a·n + s is never fused).
 *
 * Returns the number of voxels after the scan, or -1 when the caller's room or memory is
 * short (the map is then untouched).
 */

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#define OFFSET (INT64_C(1) << 20)
#define FIELD ((INT64_C(1) << 21) - 1)

enum { VOXEL, RANGE, HIT, MISS, OCCUPIED, RELEASE, CLAMP_LOW, CLAMP_HIGH, MERGE, WINDOW,
       MAX_AGE, KEEP_RADIUS, MAX_VOXELS, N_PARAMS };

typedef struct {
    int64_t *keys;   /* (cap,) packed voxel indices, sorted */
    double *centre;  /* (cap, 3) voxel centres, m */
    double *log_odds;
    double *point;   /* (cap, 3) representative points, m */
    int64_t *count;  /* hits in the representative mean */
    int64_t *label;  /* region of the latest return */
    double *seen;    /* last time seen, s */
    uint8_t *state;  /* occupied, with hysteresis */
} Map;

static double dist3(const double *a, const double *b) {
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

static int64_t key_of(const double *q, double voxel) {
    int64_t i = (int64_t)floor(q[0] / voxel) + OFFSET;
    int64_t j = (int64_t)floor(q[1] / voxel) + OFFSET;
    int64_t k = (int64_t)floor(q[2] / voxel) + OFFSET;
    return (i << 42) | (j << 21) | k;
}

static void centre_of(int64_t key, double voxel, double *c) {
    int64_t ijk[3] = {(key >> 42) & FIELD, (key >> 21) & FIELD, key & FIELD};
    for (int d = 0; d < 3; d++) c[d] = ((double)(ijk[d] - OFFSET) + 0.5) * voxel;
}

/* First index i in sorted keys[0..n) with keys[i] >= key. */
static int lower_bound(const int64_t *keys, int n, int64_t key) {
    int lo = 0, hi = n;
    while (lo < hi) {
        int mid = lo + (hi - lo) / 2;
        if (keys[mid] < key) lo = mid + 1; else hi = mid;
    }
    return lo;
}

static void copy_voxel(Map *m, int to, int from) {
    m->keys[to] = m->keys[from];
    memcpy(m->centre + 3 * to, m->centre + 3 * from, 3 * sizeof(double));
    m->log_odds[to] = m->log_odds[from];
    memcpy(m->point + 3 * to, m->point + 3 * from, 3 * sizeof(double));
    m->count[to] = m->count[from];
    m->label[to] = m->label[from];
    m->seen[to] = m->seen[from];
    m->state[to] = m->state[from];
}

static const double *seen_of_order;
static int by_recency(const void *a, const void *b) {  /* most recently seen first, stable */
    int i = *(const int *)a, j = *(const int *)b;
    double si = seen_of_order[i], sj = seen_of_order[j];
    if (si != sj) return si > sj ? -1 : 1;
    return (i > j) - (i < j);
}

int voxel_map_update(int n, int cap, int64_t *keys, double *centre, double *log_odds,
                     double *point, int64_t *count, int64_t *label, double *seen,
                     uint8_t *state, int m, const double *points, const int64_t *labels,
                     const double *p, double t, const double *par) {
    Map map = {keys, centre, log_odds, point, count, label, seen, state};
    const double voxel = par[VOXEL], range = par[RANGE], merge = par[MERGE];
    const int64_t window = (int64_t)par[WINDOW];
    if (n + m > cap) return -1;
    int64_t *hit_key = malloc((size_t)(m > 0 ? m : 1) * sizeof(int64_t));
    int *order = malloc((size_t)(m > 0 ? m : 1) * sizeof(int));
    int *slot = malloc((size_t)(m > 0 ? m : 1) * sizeof(int));
    double *reach = malloc((size_t)(n + m > 0 ? n + m : 1) * sizeof(double));
    uint8_t *hit = calloc((size_t)(n + m > 0 ? n + m : 1), 1);
    uint8_t *near = malloc((size_t)(n > 0 ? n : 1));
    if (!hit_key || !order || !slot || !reach || !hit || !near) {
        free(hit_key); free(order); free(slot); free(reach); free(hit); free(near);
        return -1;
    }
    /* Association: the voxel whose representative lies within `merge` of the return (the
     * nearest, first in key order on a tie), among those within range + merge of the
     * sensor (`near`); else the voxel the return falls in. */
    for (int v = 0; v < n; v++) near[v] = merge > 0 && dist3(point + 3 * v, p) <= range + merge;
    for (int r = 0; r < m; r++) {
        const double *q = points + 3 * r;
        hit_key[r] = key_of(q, voxel);
        if (merge <= 0 || n == 0) continue;
        double best = INFINITY;
        int nearest = -1;
        for (int v = 0; v < n; v++) {
            if (!near[v]) continue;
            double dx = q[0] - point[3 * v], dy = q[1] - point[3 * v + 1];
            double dz = q[2] - point[3 * v + 2];
            double d2 = dx * dx + dy * dy + dz * dz;
            if (d2 < best) { best = d2; nearest = v; }
        }
        if (nearest >= 0 && best < merge * merge) hit_key[r] = keys[nearest];
    }
    /* The returns in key order (stable: the first return of a voxel comes first). */
    for (int r = 0; r < m; r++) {
        int j = r;
        while (j > 0 && hit_key[order[j - 1]] > hit_key[r]) { order[j] = order[j - 1]; j--; }
        order[j] = r;
    }
    /* Misses: voxels in the map, seen by this scan, without a return. */
    const double half_diagonal = sqrt(3.0) * voxel / 2;
    for (int v = 0; v < n; v++) reach[v] = dist3(centre + 3 * v, p);
    for (int r = 0; r < m; r++) {
        int at = lower_bound(keys, n, hit_key[r]);
        if (at < n && keys[at] == hit_key[r]) hit[at] = 1;
    }
    for (int v = 0; v < n; v++) {
        int seen_now = state[v] ? reach[v] <= range - half_diagonal
                                : reach[v] <= range + half_diagonal;
        if (seen_now && !hit[v]) {
            log_odds[v] = fmax(log_odds[v] + par[MISS], par[CLAMP_LOW]);
            seen[v] = t;
        }
    }
    /* New voxels at the prior, merged into the sorted arrays from the back. */
    int fresh = 0;
    for (int a = 0; a < m; a++) {
        int r = order[a];
        if (a > 0 && hit_key[order[a - 1]] == hit_key[r]) continue;
        int at = lower_bound(keys, n, hit_key[r]);
        if (!(at < n && keys[at] == hit_key[r])) slot[fresh++] = r;
    }
    if (fresh > 0) {
        int v = n - 1, f = fresh - 1;
        for (int to = n + fresh - 1; to >= 0 && f >= 0; to--) {
            if (v >= 0 && keys[v] > hit_key[slot[f]]) {
                copy_voxel(&map, to, v);
                reach[to] = reach[v];
                v--;
            } else {
                int64_t key = hit_key[slot[f--]];
                keys[to] = key;
                centre_of(key, voxel, centre + 3 * to);
                reach[to] = dist3(centre + 3 * to, p);
                log_odds[to] = 0.0;
                point[3 * to] = point[3 * to + 1] = point[3 * to + 2] = 0.0;
                count[to] = 0;
                label[to] = 0;
                seen[to] = 0.0;
                state[to] = 0;
            }
        }
        n += fresh;
    }
    /* Hits: every hit voxel gains `hit` once; its mean takes this scan's returns, summed in
     * the order they came. */
    for (int a = 0; a < m;) {
        int r = order[a];
        int64_t key = hit_key[r];
        int v = lower_bound(keys, n, key);
        double sum[3] = {0.0, 0.0, 0.0};
        int64_t k = 0;
        int b = a;
        for (; b < m && hit_key[order[b]] == key; b++) k++;
        for (int s = 0; s < m; s++) {  /* in arrival order, as the returns came */
            if (hit_key[s] != key) continue;
            sum[0] += points[3 * s]; sum[1] += points[3 * s + 1]; sum[2] += points[3 * s + 2];
        }
        log_odds[v] = fmin(log_odds[v] + par[HIT], par[CLAMP_HIGH]);
        seen[v] = t;
        label[v] = labels[r];
        int64_t before = count[v] < window - 1 ? count[v] : window - 1;
        for (int d = 0; d < 3; d++)
            point[3 * v + d] = (point[3 * v + d] * (double)before + sum[d])
                               / (double)(before + k);
        count[v] = before + k < window ? before + k : window;
        a = b;
    }
    for (int v = 0; v < n; v++)
        state[v] = state[v] ? log_odds[v] >= par[RELEASE] : log_odds[v] >= par[OCCUPIED];
    /* Forgetting: too old, too far, back at the floor, or beyond the budget. */
    int kept = 0;
    for (int v = 0; v < n; v++) {
        hit[v] = (t - seen[v] <= par[MAX_AGE]) && (reach[v] <= par[KEEP_RADIUS])
                 && (log_odds[v] > par[CLAMP_LOW]);
        kept += hit[v];
    }
    const int budget = (int)par[MAX_VOXELS];
    if (kept > budget) {
        int *rank = malloc((size_t)kept * sizeof(int));
        if (!rank) {
            free(hit_key); free(order); free(slot); free(reach); free(hit); free(near);
            return -1;
        }
        int c = 0;
        for (int v = 0; v < n; v++) if (hit[v]) rank[c++] = v;
        seen_of_order = seen;
        qsort(rank, (size_t)kept, sizeof(int), by_recency);
        memset(hit, 0, (size_t)n);
        for (int i = 0; i < budget; i++) hit[rank[i]] = 1;
        free(rank);
    }
    int to = 0;
    for (int v = 0; v < n; v++) {
        if (!hit[v]) continue;
        if (to != v) copy_voxel(&map, to, v);
        to++;
    }
    free(hit_key); free(order); free(slot); free(reach); free(hit); free(near);
    return to;
}

/* The read-out: the representative points of the occupied voxels within `radius` of p (and
 * of a region below n_regions), grouped by region and in key order within one. Writes the
 * points to out (room for n) and the count of each region to counts (n_regions); returns
 * how many points. */
int voxel_map_regions(int n, const double *point, const int64_t *label, const uint8_t *state,
                      const double *p, double radius, int n_regions, double *out,
                      int64_t *counts) {
    memset(counts, 0, (size_t)n_regions * sizeof(int64_t));
    for (int v = 0; v < n; v++)
        if (state[v] && label[v] < n_regions && dist3(point + 3 * v, p) <= radius)
            counts[label[v]]++;
    int total = 0;
    int64_t *start = malloc((size_t)(n_regions > 0 ? n_regions : 1) * sizeof(int64_t));
    if (!start) return -1;
    for (int i = 0; i < n_regions; i++) { start[i] = total; total += (int)counts[i]; }
    for (int v = 0; v < n; v++)
        if (state[v] && label[v] < n_regions && dist3(point + 3 * v, p) <= radius) {
            memcpy(out + 3 * start[label[v]], point + 3 * v, 3 * sizeof(double));
            start[label[v]]++;
        }
    free(start);
    return total;
}
