#pragma once
// Files that are either the old version or the complete new one: the bytes go to a temporary
// file beside the target, are flushed to the disk, and the temporary is renamed over the target.
// A crash, a kill or a full disk mid-write leaves the previous file as it was.
#include <string>

namespace fruit_shape_completion {

// False with a message naming the file if any step fails (the temporary is then removed).
bool writeFileAtomically(const std::string& path, const std::string& bytes, std::string* error);

}  // namespace fruit_shape_completion
