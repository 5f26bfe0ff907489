/* main.c - build/surfd: dispatches to its subcommands (serve, render, model, volume, isosurface). */
#include <stdio.h>
#include <string.h>

#include "cli.h"

#ifndef SURFD_VERSION
#define SURFD_VERSION "dev"
#endif

int main(int argc, char **argv)
{
    if (argc >= 2 && !strcmp(argv[1], "render"))
        return cmd_render(argc - 1, argv + 1);
    if (argc >= 2 && !strcmp(argv[1], "serve"))
        return cmd_serve(argc - 1, argv + 1);
    if (argc >= 2 && (!strcmp(argv[1], "volume") || !strcmp(argv[1], "model")))
        return cmd_volume(argc - 1, argv + 1);
    if (argc >= 2 && (!strcmp(argv[1], "isosurface") || !strcmp(argv[1], "matrix")))
        return cmd_isosurface(argc - 1, argv + 1);
    if (argc >= 2 && (!strcmp(argv[1], "--version") || !strcmp(argv[1], "version"))) {
        printf("surfd %s\n", SURFD_VERSION);
        return 0;
    }
    fprintf(stderr, "usage: surfd serve [--config FILE] [--SETTING VALUE]...   (surfd serve --help)\n"
                    "       surfd render SCENE... -o OUT [options]\n"
                    "       surfd model|volume CONTOURS.json|RTSTRUCT.dcm [options]\n"
                    "       surfd isosurface VOLUME --iso V [options]\n"
                    "       surfd matrix VOLUME --iso V [options] [-o OUT.json]\n");
    return 2;
}
