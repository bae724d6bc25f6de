// parallel_slices.hpp - the worker pool that reads slices (image stacks,
// stack.cpp) and DICOM files (headers and images, dicom.cpp).
//
// Tasks k in [0, n) are taken in order from an atomic counter by up to
// `threads` workers, while the calling thread reports progress (the fraction
// of tasks done, every 50 ms) and stops the workers when the progress
// callback returns true (cancel) or throws.  On a failure the workers stop
// taking tasks; once every worker has stopped, the failure of the lowest task
// index is thrown, so the message does not depend on which thread ran first.
#ifndef ISOMEND_IO_PARALLEL_SLICES_HPP
#define ISOMEND_IO_PARALLEL_SLICES_HPP

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

namespace isomend_io {

// What tells the two callers' pools apart.
struct SlicePool {
    // What the tasks do, in messages: "out of memory while <what>",
    // "internal error while <what>: ...", "cancelled while <what>".
    const char *what;
    // The message (IoError INTERNAL) when the worker threads cannot start.
    std::string start_failure;
    // Progress: the first report at once, before any wait (true), or only
    // after the first 50 ms (false).
    bool report_at_start;
    // An exception other than IoError (out of memory, internal error) ranks
    // as the task it came from (true), or after every task (false): then an
    // IoError of any task is the one thrown, and of such exceptions the first.
    bool other_errors_at_task;
};

// Runs task(k, scratch) for k in [0, n) on up to `threads` workers (<= 0: the
// hardware's threads, at most 8; never more than n).  `scratch` is the
// worker's own buffer, empty at first and kept from one of its tasks to the
// next (a slice decoded where the caller has no memory for it).
// `progress(fraction)` (may be empty) is called on the calling thread with the
// lock not held, and once more with 1.0 when every task is done: true cancels
// (IoError CANCELLED), an exception is rethrown after the workers stop.
// Throws IoError; an IoError from a task is rethrown as it is.
void read_slices_parallel(int64_t n, int threads,
                          const std::function<void(int64_t k, std::vector<char> &scratch)> &task,
                          const std::function<bool(double)> &progress, const SlicePool &pool);

} // namespace isomend_io

#endif
