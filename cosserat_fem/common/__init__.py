"""Base: errors, logging, MPI helpers, safe file access, the JIT cache. Every layer may use it; it
uses no other."""
