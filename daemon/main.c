/* main.c - build/surfd: dispatches to its subcommands (serve, render, model, volume, isosurface,
 * matrix, store); `surfd --help` and `surfd CMD --help` print the usage on stdout and exit 0. */
#include <stdio.h>
#include <string.h>

#include "cli.h"

#ifndef SURFD_VERSION
#define SURFD_VERSION "dev"
#endif

static const struct command {
    const char *name;
    int (*run)(int argc, char **argv);
    void (*usage)(FILE *f);
} COMMANDS[] = {
    {"serve", cmd_serve, cmd_serve_usage},           {"render", cmd_render, cmd_render_usage},
    {"model", cmd_volume, cmd_volume_usage},         {"volume", cmd_volume, cmd_volume_usage},
    {"isosurface", cmd_isosurface, cmd_isosurface_usage}, {"matrix", cmd_isosurface, cmd_isosurface_usage},
    {"store", cmd_store, cmd_store_usage},
};

static void usage(FILE *f)
{
    fprintf(f, "usage: surfd serve [--config FILE] [--SETTING VALUE]...   (surfd serve --help)\n"
               "       surfd render SCENE... -o OUT [options]\n"
               "       surfd model|volume CONTOURS.json|RTSTRUCT.dcm|MATRIX.json [options]\n"
               "       surfd isosurface VOLUME --iso V [options]\n"
               "       surfd matrix VOLUME --iso V [options] [-o OUT.json]\n"
               "       surfd store check|recover [--data-dir DIR | --store URI]\n"
               "       surfd --version\n"
               "each command's options: surfd COMMAND --help\n");
}

int main(int argc, char **argv)
{
    if (argc >= 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help"))) {
        usage(stdout);
        return 0;
    }
    for (size_t c = 0; argc >= 2 && c < sizeof COMMANDS / sizeof *COMMANDS; c++) {
        if (strcmp(argv[1], COMMANDS[c].name))
            continue;
        for (int k = 2; k < argc; k++)
            if (!strcmp(argv[k], "--help") || !strcmp(argv[k], "-h")) {
                COMMANDS[c].usage(stdout);
                return 0;
            }
        return COMMANDS[c].run(argc - 1, argv + 1);
    }
    if (argc >= 2 && (!strcmp(argv[1], "--version") || !strcmp(argv[1], "version"))) {
        printf("surfd %s\n", SURFD_VERSION);
        return 0;
    }
    usage(stderr);
    return 2;
}
