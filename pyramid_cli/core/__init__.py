"""The core: errors, option choices, index geometry, borders, the filter catalogue, expressions, the parser,
exact algebra and the sigma maths. Pure Python: it imports no third-party module and nothing above it."""
