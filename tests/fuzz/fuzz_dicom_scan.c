/* fuzz_dicom_scan.c - the structure pass before DCMTK (api/dicom_scan.h): what it accepts must be
 * within its caps, and must then go through DCMTK's reader without a crash, read as an RT
 * Structure Set and as both slices of a two-part series (each reader scans it again first); and
 * blanking its identifying values must leave a structure the pass reads alike. */
#include "../../api/dicom_scan.h"
#include "../../api/dicom_series.h"
#include "../../api/rtstruct.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct dicom_scan_stats st;
    struct sf_err err = {0};
    dicom_sniff(data, size); /* the offline CLI's guess: any bytes, no reads past them */
    if (dicom_scan(data, size, "", &st, &err))
        return 0;
    /* a Part 10 file the pass accepts, without its preamble and DICM, is still taken for DICOM */
    if (size > 132 && !memcmp(data + 128, "DICM", 4) && !dicom_sniff(data + 132, size - 132))
        abort();
    if (st.max_depth > DICOM_MAX_DEPTH || st.n_elements > DICOM_MAX_ELEMENTS || st.n_disorder > DICOM_MAX_DISORDER)
        abort(); /* accepted past a cap */
    /* blanking the identifying values keeps the structure: the same pass accepts it alike */
    uint8_t *copy = malloc(size ? size : 1);
    struct dicom_scan_stats st2;
    size_t blanked;
    if (!copy)
        return 0;
    memcpy(copy, data, size);
    if (dicom_blank_identity(copy, size, "", &blanked, &err) || dicom_scan(copy, size, "", &st2, &err) ||
        st2.n_elements != st.n_elements || st2.max_depth != st.max_depth)
        abort();
    free(copy);
    struct rt_roi *rois = NULL;
    int n = 0;
    struct sf_err e2 = {0};
    if (rtstruct_read(data, size, &rois, &n, &e2) == 0)
        rtstruct_free(rois, n);
    struct part parts[2] = {{0}};
    for (int k = 0; k < 2; k++)
        parts[k].data = (const char *)data, parts[k].len = size;
    struct series s;
    struct sf_err e3 = {0};
    if (series_read(parts, 2, false, 1u << 20, 0, false, &s, &e3) == 0)
        free(s.owned);
    return 0;
}
