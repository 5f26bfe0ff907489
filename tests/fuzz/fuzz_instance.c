/* fuzz_instance.c - one DICOM instance as the DICOM node (C-STORE) and a pull (WADO-RS, C-GET) keep
 * it (daemon/dicom_node.c dicom_instance_keep): read for its UIDs and geometry
 * (api/dicom_instance.h, DCMTK after dicom_scan's pass), blanked in place, its meta written as the
 * store keeps it. What reads must name valid UIDs, its meta must be JSON, and the blanked copy
 * must read the same (blanking keeps every value's length: the layout, UIDs and geometry stay). */
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "../../api/dicom_instance.h"
#include "../../api/dicom_scan.h"
#include "../../api/series_json.h"
#include "fuzz.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    struct dicom_instance a, b;
    struct sf_err err = {0};
    if (dicom_instance_read(data, size, "", &a, &err))
        return 0;
    if (!dicom_uid_valid(a.sop_uid) || !dicom_uid_valid(a.series_uid) || !dicom_uid_valid(a.study_uid) ||
        !dicom_uid_valid(a.sop_class) || (a.frame_uid[0] && !dicom_uid_valid(a.frame_uid)) || a.frames < 1)
        abort(); /* read, yet not what the store keys by */
    char *meta = instance_meta(&a);
    if (meta) { /* (NULL: out of memory, the torture build's doing) */
        json_t *o = json_loads(meta, 0, NULL);
        if (!o)
            abort();
        json_decref(o);
        free(meta);
    }
    unsigned char *copy = malloc(size ? size : 1);
    size_t blanked = 0;
    struct sf_err e2 = {0}, e3 = {0};
    if (copy) {
        memcpy(copy, data, size);
        if (dicom_blank_identity(copy, size, "", &blanked, &e2) == 0) {
            int rc = dicom_instance_read(copy, size, "", &b, &e3);
            if ((rc && rc != SF_ENOMEM) ||
                (!rc && (strcmp(a.sop_uid, b.sop_uid) || strcmp(a.series_uid, b.series_uid) ||
                         a.rows != b.rows || a.columns != b.columns || a.frames != b.frames)))
                abort(); /* blanking changed what the store keeps of it */
        }
        free(copy);
    }
    return 0;
}
