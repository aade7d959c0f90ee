# The dolfin_rod environment as a container: the same install script, package lists and
# Debian release as the no-Docker path (./rodenv builds a trixie root with env/install.sh).
#   docker build -t dolfin_rod .
#   docker run --rm -v "$PWD/results:/project/results" dolfin_rod make test
FROM debian:trixie
COPY env/ /tmp/env/
RUN sh /tmp/env/install.sh && rm -rf /tmp/env
ENV OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader \
    OMPI_MCA_rmaps_base_oversubscribe=1 MPLBACKEND=Agg
WORKDIR /project
COPY . /project
RUN pip install --no-deps --no-build-isolation --break-system-packages -e /project
CMD ["make", "demo"]
