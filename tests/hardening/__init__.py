"""The hardening corpus (issue 19): every class of bad input, fault and interrupt, refused in one line."""
