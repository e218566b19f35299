#pragma once
// How the process shares its cores and takes its memory: settings the runtime libraries read once, when they load,
// so the program sets them and starts itself again with them.
//
// OpenMP (Open3D's odometry, fusion, ICP and pose graphs run on it, on the prepare worker) keeps its idle threads
// spinning after each parallel region by default; with GL on llvmpipe, whose threads need every core, that spinning
// took the cores the renderer was waiting for (replay of tabletop-scan with DLPV 455 -> 365 ms a frame here,
// tabletop-pt with Kinect-VAL 163 -> 121 ms).
//
// glibc's malloc gives each thread that allocates an arena of its own and backs all of them with 4 KiB pages. The
// first frames fill some 80,000 fresh pages (the room's voxel blocks, the depth filter's window statistics, the
// views' images and llvmpipe's textures), and a page fault costs about 11 us on this machine (a virtual machine):
// about 0.9 s of the first two frames of a replay. One arena, whose heap glibc asks the kernel to back with
// transparent huge pages where it allows them (2 MiB a fault), leaves those frames next to no faults: a two-frame
// replay's 100,000 become 20,000, its two starts' own (docs/real-time.md).
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace mrgi::runtime {

/// The OMP_WAIT_POLICY the program runs with when the environment sets neither it nor OMP_NUM_THREADS.
inline constexpr const char* kOmpWaitPolicy = "PASSIVE";

/// The GLIBC_TUNABLES the program runs with when the environment sets none: one malloc arena, its heap on
/// transparent huge pages (glibc 2.35 and later; an older one ignores them), and a heap that keeps what is freed:
/// blocks up to 32 MiB come from the heap, and its free top is never handed back to the kernel. By default glibc
/// trims a free top past twice its largest freed mapping, and a frame's images (a 640x480 float map is 3.5-4.7
/// MiB) were freed and touched afresh, each 2 MiB page zeroed by the kernel again (docs/real-time.md).
inline constexpr const char* kGlibcTunables =
    "glibc.malloc.hugetlb=1:glibc.malloc.arena_max=1:glibc.malloc.trim_threshold=4294967296:"
    "glibc.malloc.mmap_threshold=33554432";

/// The variables the program sets before it starts again, given the environment (`get` returns a variable's value,
/// nullopt where unset): OMP_WAIT_POLICY=kOmpWaitPolicy unless OMP_WAIT_POLICY or OMP_NUM_THREADS is set (idle OpenMP
/// threads sleep), and GLIBC_TUNABLES=kGlibcTunables unless GLIBC_TUNABLES is set. Empty: nothing to do.
std::vector<std::pair<std::string, std::string>> processSettings(
    const std::function<std::optional<std::string>(const char*)>& get);

/// Sets processSettings() of this process's environment and starts the program again with them. Call first thing in
/// main with its argv; returns when nothing was to be done (or the new start failed, in which case the program
/// carries on as it was). The second start loads the shared libraries again: 0.17 s here, once per run, against
/// 60-100 ms saved on every frame of a replay and 0.3-0.5 s of its first frames; set both variables yourself to
/// skip it (tools/process-env.sh does, for the tests).
void configureProcess(char** argv);

/// Those variables as this process runs with them, name -> value (null where unset): what a run's timings were
/// measured under (replay's, live's and the bench's summaries, "process").
nlohmann::json processSettingsInEffect();

}  // namespace mrgi::runtime
