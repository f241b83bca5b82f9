// csrbf-cli: the command-line program on one process (cli_main.cpp); the launcher `csrbf` runs it.
#include "cli_main.hpp"

int main(int argc, char** argv) { return csrbf::cli::cli_main(argc, argv, nullptr); }
