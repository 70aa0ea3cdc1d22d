/* scan.cl: exclusive prefix sum of int counts, with the grand total (list offsets).
 *
 * Algorithm: scan-then-propagate. `scan_blocks` gives each work-group a block of
 * SCAN_BLOCK = SCAN_WG·SCAN_ITEMS consecutive counts: it stages the block in local memory
 * (coalesced loads), each work-item sums its SCAN_ITEMS consecutive entries, a Hillis-Steele
 * scan over the SCAN_WG partial sums (log2 SCAN_WG steps, a fixed trip count: no barrier in a
 * data-dependent loop) gives each work-item its start, and the block's exclusive scan is
 * written out with the block total in block_sums[group]. The host scans block_sums the same
 * way (recursively, until one block remains, whose total is the grand total) and
 * `scan_add_offsets` adds each block's offset. Integer sums: the result is exact and the same
 * on every device.
 *
 * Why not pyopencl's scan: Oclgrind reports a global-memory data race in its scan_lev1 (its
 * barriers fence local memory only) and uninitialized reads; clrender's CI requires every
 * kernel to be Oclgrind-clean under --data-races --uninitialized.
 *
 * Buffers: counts int[n]; offsets int[n] (a separate buffer); block_sums int[ceil(n/SCAN_BLOCK)].
 * Work-groups: scan_blocks (SCAN_WG) per block; scan_add_offsets 1-D, any size.
 * Local memory: (SCAN_BLOCK + 2·SCAN_WG) ints, sized by the host from the device's limits.
 */
#ifndef SCAN_WG
#define SCAN_WG 128
#endif
#ifndef SCAN_ITEMS
#define SCAN_ITEMS 8
#endif
#define SCAN_BLOCK (SCAN_WG * SCAN_ITEMS)

kernel __attribute__((reqd_work_group_size(SCAN_WG, 1, 1)))
void scan_blocks(global const int* counts, int n, global int* offsets, global int* block_sums)
{
    local int items[SCAN_BLOCK];
    local int partial[2 * SCAN_WG];     /* SCAN_WG zeros, then the partial sums */
    const int lid = get_local_id(0);
    const int base = get_group_id(0) * SCAN_BLOCK;

    for (int k = 0; k < SCAN_ITEMS; ++k) {
        int i = k * SCAN_WG + lid;
        items[i] = (base + i < n) ? counts[base + i] : 0;
    }
    barrier(CLK_LOCAL_MEM_FENCE);

    const int first = lid * SCAN_ITEMS;
    int own = 0;
    for (int k = 0; k < SCAN_ITEMS; ++k) own += items[first + k];
    partial[lid] = 0;
    partial[SCAN_WG + lid] = own;
    barrier(CLK_LOCAL_MEM_FENCE);

    /* Inclusive Hillis-Steele scan; the zero prefix spares a branch for lid < step. */
    for (int step = 1; step < SCAN_WG; step <<= 1) {
        int left = partial[SCAN_WG + lid - step];
        barrier(CLK_LOCAL_MEM_FENCE);
        partial[SCAN_WG + lid] += left;
        barrier(CLK_LOCAL_MEM_FENCE);
    }

    int running = partial[SCAN_WG + lid] - own;          /* this work-item's exclusive start */
    for (int k = 0; k < SCAN_ITEMS; ++k) {
        int v = items[first + k];
        items[first + k] = running;
        running += v;
    }
    barrier(CLK_LOCAL_MEM_FENCE);

    for (int k = 0; k < SCAN_ITEMS; ++k) {
        int i = k * SCAN_WG + lid;
        if (base + i < n) offsets[base + i] = items[i];
    }
    if (lid == SCAN_WG - 1) block_sums[get_group_id(0)] = partial[2 * SCAN_WG - 1];
}

kernel void scan_add_offsets(global int* offsets, int n, global const int* block_offsets)
{
    int i = get_global_id(0);
    if (i < n) offsets[i] += block_offsets[i / SCAN_BLOCK];
}
