// The one place that says how code is shared between host and device.
// Headers that include this must use only <cstdint>/<cstring>-level facilities:
// no STL containers, no exceptions, no virtuals, no heap.
#pragma once

#if defined(__CUDACC__)
#define CWBVH_HD __host__ __device__
#define CWBVH_INLINE __forceinline__
#else
#define CWBVH_HD
#define CWBVH_INLINE inline
#endif
