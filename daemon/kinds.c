/* kinds.c - the table of job kinds (kinds.h). */
#include "kinds.h"

#include <string.h>

static const struct job_kind KINDS[] = {
    {.name = "render", .format = render_format, .media = "application/json, model/x-bpt, model/vrml or model/iges",
     .format_in_query = true, .validate = render_validate, .start = render_start,
     .result = "image/png, image/x-exr or image/tiff"},
    {.name = "volume", .format = volume_format,
     .media = "application/json (contours or a scene), application/dicom, model/x-bpt, model/vrml or model/iges",
     .format_in_query = true, .validate = volume_validate, .start = volume_start, .result = "application/json"},
    {.name = "model", .format = contour_format, .media = "application/json or application/dicom",
     .validate = model_validate_body, .start = model_start, .result = "application/json"},
    {.name = "mesh", .validate = mesh_validate, .start = mesh_start, .result = "model/stl, application/ply, model/obj, model/vnd.vtk.vtp+xml or model/vnd.vtk"},
    {.name = "patches", .validate = patches_validate, .start = patches_start, .result = "application/json"},
    {.name = "rtstruct", .validate = rtstruct_validate, .start = rtstruct_start, .result = "application/dicom"},
    {.name = "isosurface", .format = iso_format,
     .media = "application/octet-stream (raw samples, with ?dims&type), application/x-nrrd, application/x-metaimage, "
              "multipart/form-data (a DICOM series) or application/json (an FRep object)",
     .format_in_query = true, .validate = iso_validate, .start = iso_start, .result = "application/json",
     .streamed = true},
    {.name = "matrix", .format = iso_format,
     .media = "application/octet-stream (raw samples, with ?dims&type), application/x-nrrd, application/x-metaimage, "
              "multipart/form-data (a DICOM series) or application/json (an FRep object)",
     .format_in_query = true, .validate = matrix_validate, .start = matrix_start, .result = "application/json",
     .streamed = true},
    {.name = "edit", .format = edit_format, .media = "application/octet-stream (the region's raw samples)",
     .validate = edit_validate, .start = edit_start, .result = "application/json"},
};

const struct job_kind *job_kind(const char *name)
{
    for (size_t k = 0; k < sizeof KINDS / sizeof *KINDS; k++)
        if (!strcmp(KINDS[k].name, name))
            return &KINDS[k];
    return NULL;
}
