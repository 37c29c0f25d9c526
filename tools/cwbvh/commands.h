// The verbs of the `cwbvh` command. Each lives in its own file and returns
// the process exit code: 0 success, 1 bad input (invalid or unreadable file),
// 2 usage error. Errors are printed as one line: "cwbvh: error: <what>".
#pragma once

namespace cwbvh::tool {

inline constexpr int kExitOk = 0;
inline constexpr int kExitBadInput = 1;
inline constexpr int kExitUsage = 2;

/// argv[0] is the verb itself; argv[1..argc) its arguments.
int run_info(int argc, char** argv);
int run_validate(int argc, char** argv);
int run_rays(int argc, char** argv);
int run_trace(int argc, char** argv);
int run_render(int argc, char** argv);
int run_model(int argc, char** argv);

/// Prints "cwbvh: error: <message>" to stderr; returns `code`.
int error(int code, const char* message);

}  // namespace cwbvh::tool
