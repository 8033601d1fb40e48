#pragma once
// The readers under fuzzing take a path: each input is written to a file of this process
// (in /dev/shm when there is one, so a run does not wear the disk).
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <unistd.h>

namespace fuzz {

inline std::string scratchDir() {
  static const std::string dir = [] {
    const std::string d = (access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp") + std::string("/fsc_fuzz_") +
                          std::to_string(getpid());
    std::system(("mkdir -p " + d).c_str());
    return d;
  }();
  return dir;
}

inline std::string writeInput(const std::uint8_t* data, std::size_t size, const std::string& name) {
  const std::string path = scratchDir() + "/" + name;
  std::ofstream(path, std::ios::binary | std::ios::trunc).write(reinterpret_cast<const char*>(data),
                                                                 static_cast<std::streamsize>(size));
  return path;
}

}  // namespace fuzz
