/* fuzz_rtstruct.c - DICOM RT Structure Sets through the DCMTK shim: read; strip (what is stored)
 * and read the stripped copy again, which must give the same ROIs and contours. */
#include <stdio.h>

#include "../../api/rtstruct.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct rt_roi *a = NULL, *b = NULL;
    int na = 0, nb = 0;
    struct sf_err err = {0};
    if (rtstruct_read(data, size, &a, &na, &err) == 0) {
        unsigned char *kept = NULL;
        size_t n = 0;
        if (rtstruct_strip(data, size, &kept, &n, &err) == 0) {
            int again = rtstruct_read(kept, n, &b, &nb, &err); /* (out of memory: the torture test's doing) */
            if ((again && again != SF_ENOMEM) || (!again && nb != na)) {
                fprintf(stderr, "the stripped copy reads differently: %d ROIs, then %d (%s)\n", na, nb, err.message);
                abort();
            }
            for (int k = 0; !again && k < na; k++)
                if (a[k].number != b[k].number || a[k].cs.n_slices != b[k].cs.n_slices || strcmp(a[k].name, b[k].name)) {
                    fprintf(stderr, "ROI %d differs in the stripped copy\n", k);
                    abort();
                }
            rtstruct_free(b, nb);
            free(kept);
        }
        rtstruct_free(a, na);
    }
    return 0;
}
