#pragma once
// How the process shares its cores. OpenMP (Open3D's odometry, fusion, ICP and pose graphs run on it, on the
// prepare worker) keeps its idle threads spinning after each parallel region by default; with GL on llvmpipe,
// whose threads need every core, that spinning took the cores the renderer was waiting for (replay of
// tabletop-scan with DLPV 455 -> 365 ms a frame here, tabletop-pt with Kinect-VAL 163 -> 121 ms).

namespace mrgi::runtime {

/// Unless the environment already sets OMP_WAIT_POLICY or OMP_NUM_THREADS, sets OMP_WAIT_POLICY=PASSIVE (idle
/// OpenMP threads sleep) and starts the program again with it: the OpenMP runtime reads its environment once,
/// when it loads, before main. Call first thing in main with its argv; returns when nothing was to be done (or
/// the new start failed, in which case the program carries on as it was). The second start loads the shared
/// libraries again: 0.17 s here, once per run (`mrgi --version` 0.16 -> 0.33 s), against 60-100 ms saved on every
/// frame of a replay; set OMP_WAIT_POLICY yourself to skip it.
void shareCoresWithGl(char** argv);

}  // namespace mrgi::runtime
