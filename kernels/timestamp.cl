/* timestamp.cl: a profiling timestamp in a command queue, for devices whose marker events carry
 * no time (Intel's CPU runtime: clEnqueueMarker events report start = end = 0, its kernel events
 * real ones). clrender/device/timestamps.py launches it between passes; the launch's event start/end
 * bracket that point of the in-order queue, as a marker's would.
 *
 * Algorithm: none; the kernel does nothing, its launch is the timestamp.
 * Buffers: none.
 * Work-groups: launched with global size 1, local size 1; no barriers, no local memory.
 */

kernel void timestamp(void)
{
}
