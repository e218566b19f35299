#pragma once
// The mrgi command line's entry point, apart from its CLI11 declarations (app/commands.h) so that the
// executable's own source includes nothing heavy.

namespace mrgi::app {
/// Parses argv and runs the one subcommand named: its exit status (2 for a bad flag, with one line on stderr
/// naming it; 1 for a failure, one line naming the file or problem).
int run(int argc, char** argv);
}  // namespace mrgi::app
