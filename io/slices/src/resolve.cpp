// resolve.cpp - from what the user typed to an ordered list of slice files.
//
// Ordering is what users of ImageJ/Fiji, ITK, scikit-image and tifffile
// expect: a folder or a glob is sorted *naturally* (slice_2 before slice_10:
// runs of digits compare as numbers, everything else case-insensitively,
// ties broken by plain byte order so the result never depends on readdir);
// a printf pattern is ordered by index; an explicit list keeps its order.
//
// A folder contributes the images with its most common image extension
// (recognised by the image library's extension list, image.hpp), so a stray preview.png or
// notes.txt next to 300 TIFFs is ignored; a tie between two extensions is an
// error that asks for a glob, rather than a guess.
#include "image.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <map>
#include <set>

#include <dirent.h>
#include <glob.h>
#include <sys/stat.h>


namespace isomend_io {

bool natural_less(const std::string &a, const std::string &b) {
    size_t i = 0, j = 0;
    while (i < a.size() && j < b.size()) {
        unsigned char ca = (unsigned char)a[i], cb = (unsigned char)b[j];
        if (std::isdigit(ca) && std::isdigit(cb)) {
            size_t i0 = i, j0 = j;
            while (i0 < a.size() && a[i0] == '0') i0++;
            while (j0 < b.size() && b[j0] == '0') j0++;
            size_t i1 = i0, j1 = j0;
            while (i1 < a.size() && std::isdigit((unsigned char)a[i1])) i1++;
            while (j1 < b.size() && std::isdigit((unsigned char)b[j1])) j1++;
            if (i1 - i0 != j1 - j0) return (i1 - i0) < (j1 - j0);
            int c = a.compare(i0, i1 - i0, b, j0, j1 - j0);
            if (c != 0) return c < 0;
            i = i1;
            j = j1;
            continue;
        }
        int la = std::tolower(ca), lb = std::tolower(cb);
        if (la != lb) return la < lb;
        i++;
        j++;
    }
    if (a.size() - i != b.size() - j) return (a.size() - i) < (b.size() - j);
    return a < b;
}

// Finds the one integer conversion of a printf pattern: returns its position
// and length, or npos.  "%%" is a literal percent sign.  Sets *count to the
// number of conversions of any kind found.
static size_t find_conversion(const std::string &p, size_t *len, int *count) {
    size_t found = std::string::npos;
    *count = 0;
    for (size_t i = 0; i < p.size(); i++) {
        if (p[i] != '%') continue;
        if (i + 1 < p.size() && p[i + 1] == '%') {
            i++;
            continue;
        }
        size_t k = i + 1;
        while (k < p.size() && std::isdigit((unsigned char)p[k])) k++;
        (*count)++;
        if (k < p.size() && (p[k] == 'd' || p[k] == 'i' || p[k] == 'u')) {
            if (found == std::string::npos) {
                found = i;
                *len = k + 1 - i;
            }
        } else {
            found = std::string::npos; // a conversion we do not support
            *count = 99;
            break;
        }
    }
    return *count == 1 ? found : std::string::npos;
}

bool is_printf_pattern(const std::string &path) {
    size_t len = 0;
    int count = 0;
    return find_conversion(path, &len, &count) != std::string::npos;
}

std::string format_pattern(const std::string &p, int64_t index) {
    size_t len = 0;
    int count = 0;
    size_t pos = find_conversion(p, &len, &count);
    if (pos == std::string::npos) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "not a pattern: " + p);
    std::string spec = p.substr(pos + 1, len - 2); // flags and width
    bool zero = !spec.empty() && spec[0] == '0';
    size_t width = spec.empty() ? 0 : (size_t)std::strtoul(spec.c_str(), nullptr, 10);
    if (width > 64) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "pattern width too large: " + p);
    bool negative = index < 0;
    uint64_t mag = negative ? (uint64_t)(-(index + 1)) + 1 : (uint64_t)index;
    std::string digits = std::to_string(mag);
    size_t used = digits.size() + (negative ? 1 : 0);
    std::string num;
    if (used < width) {
        if (zero)
            num = std::string(negative ? "-" : "") + std::string(width - used, '0') + digits;
        else
            num = std::string(width - used, ' ') + (negative ? "-" : "") + digits;
    } else {
        num = (negative ? "-" : "") + digits;
    }
    std::string out;
    for (size_t i = 0; i < p.size(); i++) {
        if (i == pos) {
            out += num;
            i += len - 1;
        } else if (p[i] == '%' && i + 1 < p.size() && p[i + 1] == '%') {
            out += '%';
            i++;
        } else {
            out += p[i];
        }
    }
    return out;
}

bool has_glob_chars(const std::string &path) {
    return path.find_first_of("*?[") != std::string::npos;
}

bool is_directory(const std::string &path) {
    struct stat st;
    return ::stat(path.c_str(), &st) == 0 && S_ISDIR(st.st_mode);
}

bool is_regular_file(const std::string &path) {
    struct stat st;
    return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string lower_extension(const std::string &path) {
    size_t slash = path.find_last_of('/');
    size_t dot = path.find_last_of('.');
    if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return "";
    std::string e = path.substr(dot + 1);
    for (char &c : e) c = (char)std::tolower((unsigned char)c);
    return e;
}

std::vector<std::string> list_folder(const std::string &dir) {
    DIR *d = ::opendir(dir.c_str());
    if (!d)
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND,
                      dir + ": cannot open folder: " + std::strerror(errno));
    std::vector<std::string> names;
    std::string base = dir;
    if (!base.empty() && base.back() != '/') base += '/';
    while (struct dirent *e = ::readdir(d)) {
        if (e->d_name[0] == '.') continue; // hidden files, . and ..
        std::string full = base + e->d_name;
        if (is_regular_file(full)) names.push_back(full);
    }
    ::closedir(d);
    std::set<std::string> known = image_extensions();
    std::map<std::string, size_t> counts;
    for (const auto &n : names) {
        std::string e = lower_extension(n);
        if (!e.empty() && known.count(e)) counts[e]++;
    }
    if (counts.empty())
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND,
                      dir + ": folder contains no image files (" + std::to_string(names.size()) +
                          " other files)");
    std::string best;
    size_t best_n = 0;
    bool tie = false;
    std::string tie_with;
    for (const auto &kv : counts) {
        if (kv.second > best_n) {
            best = kv.first;
            best_n = kv.second;
            tie = false;
        } else if (kv.second == best_n) {
            tie = true;
            tie_with = kv.first;
        }
    }
    if (tie)
        throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT,
                      dir + ": as many ." + best + " as ." + tie_with + " images (" +
                          std::to_string(best_n) + " each); choose with a glob such as '" + base +
                          "*." + best + "'");
    std::vector<std::string> out;
    for (const auto &n : names)
        if (lower_extension(n) == best) out.push_back(n);
    std::sort(out.begin(), out.end(), natural_less);
    return out;
}

std::vector<std::string> expand_glob(const std::string &pattern) {
    glob_t g;
    std::memset(&g, 0, sizeof g);
    int rc = ::glob(pattern.c_str(), GLOB_NOSORT, nullptr, &g);
    std::vector<std::string> out;
    if (rc == 0) {
        for (size_t i = 0; i < g.gl_pathc; i++)
            if (is_regular_file(g.gl_pathv[i])) out.emplace_back(g.gl_pathv[i]);
    }
    ::globfree(&g);
    if (rc == GLOB_NOSPACE) throw IoError(ISOMEND_IO_ERR_OUT_OF_MEMORY, pattern + ": out of memory");
    if (out.empty())
        throw IoError(ISOMEND_IO_ERR_NOT_FOUND, pattern + ": no file matches this pattern");
    std::sort(out.begin(), out.end(), natural_less);
    return out;
}

std::vector<std::string> expand_pattern(const std::string &pattern, int64_t first, int64_t count,
                                        int64_t step) {
    if (step == 0) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "--step must not be 0");
    if (count < 0) throw IoError(ISOMEND_IO_ERR_INVALID_ARGUMENT, "--count must be >= 0");
    std::vector<std::string> out;
    if (count > 0) {
        for (int64_t i = 0; i < count; i++) {
            int64_t idx = first + i * step;
            std::string p = format_pattern(pattern, idx);
            if (!is_regular_file(p))
                throw IoError(ISOMEND_IO_ERR_NOT_FOUND,
                              p + ": slice " + std::to_string(i) + " of the pattern (index " +
                                  std::to_string(idx) + ") not found");
            out.push_back(p);
        }
        return out;
    }
    for (int64_t idx = first;; idx += step) {
        std::string p = format_pattern(pattern, idx);
        if (!is_regular_file(p)) {
            if (out.empty())
                throw IoError(ISOMEND_IO_ERR_NOT_FOUND,
                              p + ": first slice of the pattern (index " + std::to_string(idx) +
                                  ") not found; set the first index (--first)");
            break;
        }
        out.push_back(p);
        if (out.size() > 10000000) break;
    }
    return out;
}

} // namespace isomend_io
