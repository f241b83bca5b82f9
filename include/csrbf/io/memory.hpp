// What a process holds, for limits that bound the whole process (--memory-limit).
#pragma once

#include <string>

namespace csrbf::io {

/// This process's resident memory now, in bytes (Linux: /proc/self/statm); 0 where unknown.
double resident_bytes() noexcept;
/// This process's address-space size now (VmSize), in bytes; 0 where unknown.
double address_space_bytes() noexcept;

/// The part of a whole-process limit (bytes) that is still free for the work that follows: limit
/// minus resident_bytes(). Throws FileError naming the option and both figures when less than a
/// twentieth of the limit is left (the program, its libraries and what it has read already hold it).
double memory_left(double limit_bytes, const std::string& option = "--memory-limit");

/// For a limit error of work given `left` of limit_bytes: " (--memory-limit L GiB: csrbf and what it
/// read hold H GiB of it, leaving F GiB for the fit)", so that the figures of the message add up.
std::string memory_share(double limit_bytes, double left, const std::string& option = "--memory-limit");

}  // namespace csrbf::io
