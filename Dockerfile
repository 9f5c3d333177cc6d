# posereg in a container: the command line, Mesa's software Vulkan driver (lavapipe: the GPU path
# runs without a GPU; on a GPU node the NVIDIA container toolkit's Vulkan driver is found instead)
# and the Python package (`import posereg`). Built from this repository:
#
#   docker build -t posereg .
#   docker run --rm -v "$PWD:/data" -w /data posereg demo
#
# For Apptainer on a cluster, posereg.def builds a .sif from this image (README, "On a cluster").
# BASE is any Debian bookworm image (a local one where Docker Hub cannot be reached). Behind a
# proxy that re-signs TLS (common on hospital networks), give its CA certificates:
#   docker build --build-arg EXTRA_CA_CERTS="$(cat proxy-ca.pem)" -t posereg .
ARG BASE=debian:bookworm-slim

FROM ${BASE} AS base
ARG EXTRA_CA_CERTS=""
RUN apt-get update \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends ca-certificates \
    && rm -rf /var/lib/apt/lists/* \
    && printf '%s\n' "$EXTRA_CA_CERTS" >/usr/local/share/ca-certificates/extra.crt \
    && update-ca-certificates
# rustup, cargo and pip trust the system's certificates (so the ones above count too).
ENV SSL_CERT_FILE=/etc/ssl/certs/ca-certificates.crt \
    CARGO_HTTP_CAINFO=/etc/ssl/certs/ca-certificates.crt \
    PIP_CERT=/etc/ssl/certs/ca-certificates.crt

FROM base AS build
RUN apt-get update \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
        curl gcc libc6-dev python3 python3-venv \
    && rm -rf /var/lib/apt/lists/*
RUN curl -sSfo /tmp/rustup-init \
        https://static.rust-lang.org/rustup/dist/x86_64-unknown-linux-gnu/rustup-init \
    && chmod +x /tmp/rustup-init \
    && /tmp/rustup-init -y --profile minimal --default-toolchain 1.95.0 \
    && rm /tmp/rustup-init
ENV PATH=/root/.cargo/bin:$PATH
WORKDIR /src
COPY . .
RUN cargo build --release --locked --bin posereg \
    && python3 -m venv /opt/maturin \
    && /opt/maturin/bin/pip install --quiet 'maturin>=1.5,<2' \
    && /opt/maturin/bin/maturin build --release --locked --out /wheels

FROM base
RUN apt-get update \
    && DEBIAN_FRONTEND=noninteractive apt-get install -y --no-install-recommends \
        libvulkan1 mesa-vulkan-drivers python3 python3-venv \
    && rm -rf /var/lib/apt/lists/*
COPY --from=build /src/target/release/posereg /usr/local/bin/posereg
COPY --from=build /wheels /wheels
RUN python3 -m venv /opt/posereg \
    && /opt/posereg/bin/pip install --quiet /wheels/*.whl \
    && rm -rf /wheels
# Mesa wants a private runtime folder; posereg writes where it is run (mount your data there).
ENV PATH=/opt/posereg/bin:$PATH XDG_RUNTIME_DIR=/tmp/runtime
RUN mkdir -m 700 /tmp/runtime
ENTRYPOINT ["posereg"]
CMD ["--help"]
