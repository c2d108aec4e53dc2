// The single SonicBoom executable: all logic lives in sonicboom::experiments.
#include "sonicboom/experiments/cli.h"

int main(int argc, char** argv) {
  return sonicboom::experiments::RunCli(argc, argv);
}
