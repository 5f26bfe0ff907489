/* gauss.h - Gauss–Legendre quadrature on [0, 1]: the fixed rules the measures use (n nodes are exact
 * for polynomials of degree 2n - 1), and any order on demand. */
#ifndef SURFD_GAUSS_H
#define SURFD_GAUSS_H

static const double GL3_X[3] = {0.112701665379258, 0.5, 0.887298334620742};
static const double GL3_W[3] = {0.277777777777778, 0.444444444444444, 0.277777777777778};
static const double GL4_X[4] = {0.069431844202974, 0.330009478207572, 0.669990521792428, 0.930568155797026};
static const double GL4_W[4] = {0.173927422568727, 0.326072577431273, 0.326072577431273, 0.173927422568727};
static const double GL5_X[5] = {0.046910077030668, 0.230765344947158, 0.5, 0.769234655052842, 0.953089922969332};
static const double GL5_W[5] = {0.118463442528095, 0.239314335249683, 0.284444444444444, 0.239314335249683,
                                0.118463442528095};
static const double GL8_X[8] = {0.019855071751232, 0.101666761293187, 0.237233795041836, 0.408282678752175,
                                0.591717321247825, 0.762766204958164, 0.898333238706813, 0.980144928248768};
static const double GL8_W[8] = {0.050614268145188, 0.111190517226687, 0.156853322938944, 0.181341891689181,
                                0.181341891689181, 0.156853322938944, 0.111190517226687, 0.050614268145188};

/* The n-node rule (n >= 1): nodes x[0..n-1] and weights w[0..n-1] on [0, 1]. */
void gauss_legendre(int n, double *x, double *w);

#endif
