"""Transfer: the quadrature over the direction set, its statistics, contact tangents, mesh points, bounces."""
