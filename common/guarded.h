// Long-lived threads (the client's stages, the server's assembler) must never
// end in std::terminate: an exception that escapes a std::thread's function,
// of any type, aborts the process with no message and no MPI abort, leaving
// the other ranks to wait. runGuarded catches everything and says what.
#pragma once

#include <exception>
#include <string>

namespace dmmr {

// Runs `body`; an exception escaping it (std::exception or any other type)
// is passed to `on_escape` as a description, on the same thread.
template <typename Body, typename OnEscape>
void runGuarded(Body&& body, OnEscape&& on_escape) noexcept {
  try {
    try {
      body();
    } catch (const std::exception& e) {
      on_escape(std::string(e.what()));
    } catch (...) {
      on_escape(std::string("an exception that is not a std::exception"));
    }
  } catch (...) {
    // on_escape itself failed (the report could not be sent): nothing more
    // can be said here; the caller goes on and drains.
  }
}

}  // namespace dmmr
