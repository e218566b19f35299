#pragma once
// The flags' side of the one rule at the boundary (capture/checks.h): every number a flag takes is finite
// and in its range, every value non-empty, each error one line naming the flag (exit 2).
#include <CLI/CLI.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "capture/error.h"

namespace mrgi::app {

/// A flag's value that only the command can judge (capture/error.h): main prints "mrgi: <flag>: <problem>" and
/// exits 2, as for a value CLI11 refused.
using FlagError = capture::FlagError;

/// A number in [lo, hi] (finite; bounds printed as "%g"). Replaces CLI::Range, whose message prints
/// DBL_MAX as 309 digits and which lets nan through.
CLI::Validator numberIn(double lo, double hi);
/// A number strictly above lo and at most hi.
CLI::Validator numberAbove(double lo, double hi);

/// Comma-separated numbers in one value ("fx,fy,cx,cy"): exactly `count` of them, each finite and in
/// [lo, hi]; `words` are accepted as they are ("camera", "marker"). parseNumbers reads a value it passed.
CLI::Validator numberList(int count, double lo, double hi, std::vector<std::string> words = {});
std::vector<double> parseNumbers(const std::string& text);

/// An AprilTag family libapriltag ships (capture::kTagFamilies).
CLI::Validator tagFamily();
/// Throws FlagError(idFlag) when id is not one of family's ids.
void checkTagId(const std::string& family, int id, const std::string& idFlag);

/// After every subcommand has registered its options: each option that takes floating-point numbers
/// refuses nan and inf, and each option refuses an empty value ("--out ''") unless it was marked with
/// allowEmpty (replay --mp4 "" writes no video).
void allowEmpty(CLI::Option* option);
void checkEveryValue(CLI::App& app);

}  // namespace mrgi::app
