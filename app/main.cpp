// The mrgi executable: the command line (app/commands.h) parses the arguments and runs one subcommand.
#include "app/run.h"

int main(int argc, char** argv) { return mrgi::app::run(argc, argv); }
