#pragma once
// Process-wide allocation behaviour for the frame loop.
#include <malloc.h>

namespace mrgi::capture {

/// Every frame allocates and frees the same large images (a 640 x 480 four-channel float image is 4.9 MB).
/// glibc serves blocks that large with mmap and unmaps them on free, so every frame page-faults its images
/// in again: the depth filter alone took 130 ms of a 640 x 480 frame that way, 18 ms from reused memory.
/// After this, blocks up to 32 MiB (glibc's ceiling) come from the heap, which is not trimmed below 512 MiB
/// of free space: memory stays mapped for the next frame, and the footprint is the largest frame's. Call
/// once at start (mrgi, the benchmarks).
inline void keepFrameMemory() {
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 512 << 20);
}

}  // namespace mrgi::capture
