// libFuzzer target for cwbvh::validate. Random mutations almost never keep
// the meta checksum right, which would stop the fuzzer at rule 3005; so for
// half of the inputs the harness first "reseals" a copy (recomputes the meta
// and payload checksums wherever the fields are in range), which lets it
// reach the table and content rules. The other half is validated as is. A
// file that passes is walked, and the deep checks (D1-D6) run on it: they size
// tables by counts from the file (the PMAP total: issue 21 finding 1).
#include <cstdint>
#include <cstring>
#include <vector>

#include "cwbvh/format/validate.h"
#include "fuzz_file.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    cwbvh::ValidateOptions options;
    options.verify_checksums = size % 3 != 0;
    if (size % 2 == 0) {
        (void)cwbvh::validate({data, size}, options);
        return 0;
    }
    std::vector<uint8_t> copy(data, data + size);
    cwbvh::fuzz::reseal(copy);
    cwbvh::FileLayout layout;
    const cwbvh::Result r = cwbvh::validate(copy, options, &layout);
    if (r.ok()) {
        // A file that passes must be safe to walk: touch every section's bytes.
        volatile uint8_t sink = 0;
        for (const cwbvh::SectionEntry& e : layout.table)
            for (uint8_t b : layout.payload(e)) sink = sink ^ b;
        (void)cwbvh::fuzz::FileSections(layout).deep_checks_pass();
    }
    return 0;
}
