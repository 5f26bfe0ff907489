/* cli.h - the subcommands of build/surfd, one file each. Each returns the process exit code:
 * 0 done, 1 failed (message on stderr), 2 usage. */
#ifndef SURFD_CLI_H
#define SURFD_CLI_H

#include <stdio.h>

int cmd_render(int argc, char **argv);
int cmd_serve(int argc, char **argv);
int cmd_volume(int argc, char **argv);
int cmd_isosurface(int argc, char **argv);
int cmd_store(int argc, char **argv);
/* Their usage texts (`surfd CMD --help` prints one on stdout and exits 0). */
void cmd_render_usage(FILE *f);
void cmd_serve_usage(FILE *f);
void cmd_volume_usage(FILE *f);
void cmd_isosurface_usage(FILE *f);
void cmd_store_usage(FILE *f);

#include <stddef.h>
/* A whole file (NUL-terminated, caller frees), or NULL after saying why on stderr. Files up to
 * max_len bytes. */
char *cli_read_all(const char *path, size_t *len, size_t max_len);
/* 0, or -1 after saying why. */
int cli_write_all(const char *path, const char *data, size_t len);

#endif
