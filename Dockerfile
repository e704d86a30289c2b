# cosserat-fem on Debian 12 (DOLFINx 0.5.2 from Debian's archive).
#   docker build -t cosserat-fem .      (or: podman build -t cosserat-fem .)
#   docker run --rm cosserat-fem make test
FROM debian:bookworm

ENV DEBIAN_FRONTEND=noninteractive \
    OMPI_ALLOW_RUN_AS_ROOT=1 \
    OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    OMPI_MCA_rmaps_base_oversubscribe=1 \
    OMPI_MCA_mpi_yield_when_idle=1 \
    OMPI_MCA_hwloc_base_binding_policy=none \
    VENV=/opt/venv

WORKDIR /src
# Layer 1: the Debian packages, from the set-up script alone, so that a source change does not
# reinstall them (the script is run with an empty project: it stops after the apt step).
COPY .ci/setup.sh .ci/setup.sh
RUN SETUP_APT_ONLY=1 bash .ci/setup.sh && rm -rf /var/lib/apt/lists/*

# Layer 2: the project, installed by the same script into /opt/venv. PIP_CERT (a build
# argument, unset by default) points pip at an extra CA bundle behind a TLS-intercepting proxy.
ARG PIP_CERT
COPY . .
RUN bash .ci/setup.sh
ENV PATH=/opt/venv/bin:$PATH
CMD ["make", "test", "VENV=/opt/venv"]
