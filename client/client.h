// A dmmr client (ranks 1..N): renders the object list of each job into its
// region with the shared drawing code and returns the compressed pixels.
#pragma once

#include <string>

#include "compress.h"
#include "camera.h"
#include "gl_context.h"
#include "mpi_comm.h"

namespace dmmr {

struct ClientOptions {
  std::string scene;
  ViewOptions view;
  ContextOptions context;
  Codec codec = Codec::LZ4;
};

// Runs until the server says Shutdown. Returns the process exit status.
int runClient(Comm& comm, const ClientOptions& opts);

}  // namespace dmmr
