// parallel_slices.cpp - the worker pool of parallel_slices.hpp.
//
// The workers only read the shared state through atomics (the next task, the
// count of tasks done, the stop flag); the first failure is kept under a mutex
// with its task index, and the calling thread sleeps on a condition variable
// that every finished task signals, so progress is reported from the calling
// thread (the C API's callbacks need not be thread-safe).
#include "parallel_slices.hpp"
#include "internal.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <system_error>
#include <thread>

namespace isomend_io {

int reader_threads_for(int threads) { return threads > 0 ? threads : std::min(isomend_cores(), 8); }

void read_slices_parallel(int64_t n, int threads,
                          const std::function<void(int64_t k, std::vector<char> &scratch)> &task,
                          const std::function<bool(double)> &progress, const SlicePool &pool) {
    threads = (int)std::max<int64_t>(1, std::min<int64_t>(reader_threads_for(threads), n));
    const std::string what = pool.what;
    std::atomic<int64_t> next{0}, done{0};
    std::atomic<bool> stop{false};
    std::mutex mu;
    std::condition_variable cv;
    int64_t error_index = -1;
    isomend_io_status error_status = ISOMEND_IO_OK;
    std::string error_message;
    auto fail = [&](int64_t k, isomend_io_status st, const std::string &m) {
        std::lock_guard<std::mutex> lock(mu);
        if (error_index < 0 || k < error_index) {
            error_index = k;
            error_status = st;
            error_message = m;
        }
        stop.store(true);
    };
    auto worker = [&] {
        std::vector<char> scratch;
        for (;;) {
            if (stop.load()) break;
            int64_t k = next.fetch_add(1);
            if (k >= n) break;
            const int64_t other = pool.other_errors_at_task ? k : n;
            try {
                task(k, scratch);
            } catch (const IoError &e) {
                fail(k, e.status, e.what());
            } catch (const std::bad_alloc &) {
                fail(other, ISOMEND_IO_ERR_OUT_OF_MEMORY, "out of memory while " + what);
            } catch (const std::exception &e) {
                fail(other, ISOMEND_IO_ERR_INTERNAL, "internal error while " + what + ": " + e.what());
            }
            done.fetch_add(1);
            cv.notify_one();
        }
        cv.notify_one();
    };
    std::vector<std::thread> workers;
    auto join_all = [&] {
        stop.store(true);
        for (auto &th : workers) th.join();
    };
    try {
        for (int t = 0; t < threads; t++) workers.emplace_back(worker);
    } catch (const std::system_error &) {
        join_all();
        throw IoError(ISOMEND_IO_ERR_INTERNAL, pool.start_failure);
    }
    bool cancelled = false;
    auto last = std::chrono::steady_clock::now();
    if (pool.report_at_start) last -= std::chrono::seconds(1);
    {
        std::unique_lock<std::mutex> lock(mu);
        while (done.load() < n && !stop.load()) {
            auto now = std::chrono::steady_clock::now();
            if (progress && now - last >= std::chrono::milliseconds(50)) {
                last = now;
                double f = (double)done.load() / (double)n;
                lock.unlock();
                bool c = false;
                try {
                    c = progress(f);
                } catch (...) {
                    join_all();
                    throw;
                }
                lock.lock();
                if (c) {
                    cancelled = true;
                    stop.store(true);
                }
            }
            cv.wait_for(lock, std::chrono::milliseconds(50));
        }
    }
    for (auto &th : workers) th.join();
    if (error_index >= 0) throw IoError(error_status, error_message);
    if (cancelled || (progress && progress(1.0)))
        throw IoError(ISOMEND_IO_ERR_CANCELLED, "cancelled while " + what);
}

} // namespace isomend_io
