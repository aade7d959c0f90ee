# The dolfin_rod environment as a container: the same install script and per-release
# package lists as the no-Docker path (./rodenv builds a Debian root with env/install.sh).
#   docker build -t dolfin_rod .                              DOLFINx 0.9  (Debian trixie)
#   docker build --build-arg DEBIAN=sid -t dolfin_rod:0.11 .  DOLFINx 0.11 (Debian sid)
#   docker run --rm -v "$PWD/results:/project/results" dolfin_rod make test
# Inside, python3 imports the image's DOLFINx, so ./rodenv and make use it directly.
ARG DEBIAN=trixie
FROM debian:${DEBIAN}
ARG DEBIAN
COPY env/ /tmp/env/
RUN sh /tmp/env/install.sh "${DEBIAN}" && rm -rf /tmp/env
ENV OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader \
    OMPI_MCA_rmaps_base_oversubscribe=1 UCX_MEM_EVENTS=no MPLBACKEND=Agg
WORKDIR /project
COPY . /project
RUN pip install --no-deps --no-build-isolation --break-system-packages -e /project
CMD ["make", "demo"]
