/// @file errors.h
/// @brief Exception types of the core; the bindings map each to one Python exception.
///
/// Every message names what was wrong: the file, the grid and the cause.
#pragma once

#include <stdexcept>
#include <string>

namespace pcvr {

/// Base of all PCVR errors.
struct Error : std::runtime_error {
    using std::runtime_error::runtime_error;
};
/// A path that does not exist (Python: FileNotFoundError).
struct FileNotFound : Error {
    using Error::Error;
};
/// A file that exists but is not a readable VDB: truncated, corrupt, wrong format (Python: pcvr_native.VDBReadError, an OSError).
struct VdbReadError : Error {
    using Error::Error;
};
/// A grid that cannot be rendered: unknown name, vector values, unsupported transform (Python: pcvr_native.GridError, a ValueError).
struct GridError : Error {
    using Error::Error;
};
/// A camera that cannot project: singular or non-finite matrices, empty image (Python: pcvr_native.CameraError, a ValueError).
struct CameraError : Error {
    using Error::Error;
};
/// Any other invalid argument, e.g. an unknown method name (Python: ValueError).
struct InvalidArgument : Error {
    using Error::Error;
};
/// A render that would need more memory than it may use (Python: MemoryError).
struct OutOfMemory : Error {
    using Error::Error;
};
/// The caller asked to stop (Python: pcvr_native.RenderCancelled).
struct Cancelled : Error {
    using Error::Error;
};

}  // namespace pcvr
