/* Evaluates the C rendering of gatetwin.plant.elementary on arguments read from stdin, one
 * "<function> <x bits> <y bits>" line each (IEEE 754 bit patterns in hexadecimal, y read by
 * pow only), and prints each result's bit pattern in hexadecimal: the same text on every
 * platform where the functions give the same bits. Bit patterns, not decimal text, so that no
 * C library's number formatting or parsing takes part. Exit 2 on a line it cannot read. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "elementary.h"

static double from_bits(uint64_t bits)
{
    double x;
    memcpy(&x, &bits, sizeof x);
    return x;
}

static int evaluate(const char *name, double x, double y, double *out)
{
    if (strcmp(name, "exp") == 0) *out = gt_exp(x);
    else if (strcmp(name, "expm1") == 0) *out = gt_expm1(x);
    else if (strcmp(name, "log") == 0) *out = gt_log(x);
    else if (strcmp(name, "log1p") == 0) *out = gt_log1p(x);
    else if (strcmp(name, "sin") == 0) *out = gt_sin(x);
    else if (strcmp(name, "cos") == 0) *out = gt_cos(x);
    else if (strcmp(name, "pow") == 0) *out = gt_pow(x, y);
    else return -1;
    return 0;
}

int main(void)
{
    char line[128];
    while (fgets(line, sizeof line, stdin) != NULL) {
        char *name = strtok(line, " \n"), *xs = strtok(NULL, " \n"), *ys = strtok(NULL, " \n");
        double result;
        uint64_t bits;
        if (name == NULL || xs == NULL || ys == NULL) return 2;
        if (evaluate(name, from_bits(strtoull(xs, NULL, 16)), from_bits(strtoull(ys, NULL, 16)),
                     &result) != 0) return 2;
        memcpy(&bits, &result, sizeof bits);
        printf("%08lx%08lx\n", (unsigned long)(bits >> 32), (unsigned long)(bits & 0xffffffffu));
    }
    return 0;
}
