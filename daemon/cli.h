/* cli.h - the subcommands of build/surfd, one file each. Each returns the process exit code:
 * 0 done, 1 failed (message on stderr), 2 usage. */
#ifndef SURFD_CLI_H
#define SURFD_CLI_H

int cmd_render(int argc, char **argv);
int cmd_serve(int argc, char **argv);
int cmd_volume(int argc, char **argv);

#endif
