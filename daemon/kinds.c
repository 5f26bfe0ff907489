/* kinds.c - the table of job kinds (kinds.h). */
#include "kinds.h"

#include <string.h>

static const struct job_kind KINDS[] = {
    {"render", render_format, "application/json, model/x-bpt or model/vrml", true, render_validate, render_start,
     "image/png, image/x-exr or image/tiff"},
    {"volume", volume_format, "application/json (contours or a scene), application/dicom, model/x-bpt or model/vrml",
     false, volume_validate, volume_start, "application/json"},
    {"model", contour_format, "application/json or application/dicom", false, model_validate_body, model_start,
     "application/json"},
    {"mesh", NULL, NULL, false, mesh_validate, mesh_start, "model/stl, application/x-ply or model/obj"},
    {"patches", NULL, NULL, false, patches_validate, patches_start, "application/json"},
    {"isosurface", iso_format,
     "application/octet-stream (raw samples, with ?dims&type), application/x-nrrd or application/x-metaimage", true,
     iso_validate, iso_start, "application/json"},
};

const struct job_kind *job_kind(const char *name)
{
    for (size_t k = 0; k < sizeof KINDS / sizeof *KINDS; k++)
        if (!strcmp(KINDS[k].name, name))
            return &KINDS[k];
    return NULL;
}
