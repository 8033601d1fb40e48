#pragma once
// Files that are either the old version or the complete new one: the bytes go to a temporary
// file beside the target, are flushed to the disk, and the temporary is renamed over the target.
// A crash, a kill or a full disk mid-write leaves the previous file as it was.
#include <string>
#include <vector>

namespace fruit_shape_completion {

// False with a message naming the file if any step fails (the temporary is then removed).
bool writeFileAtomically(const std::string& path, const std::string& bytes, std::string* error);

// Removes the temporaries that writes to `path` killed mid-way left beside it (its name plus
// ".tmp" and six characters) once they are `min_age` seconds old, so that a write still in
// progress keeps its own. Returns the names removed, for the caller's warning.
std::vector<std::string> removeStaleTemporaries(const std::string& path, double min_age = 60.0);

}  // namespace fruit_shape_completion
