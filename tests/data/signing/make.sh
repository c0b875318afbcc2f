#!/usr/bin/env bash
# Test-only keys and certificates for the signed DCCs (issue 46): a test CA,
# the laboratory's signing certificate from it (lab.pem holds the leaf, then
# the CA: a chain), a second one for rotation, and the refused kinds — an
# RSA-1024 key, a P-384 key, the laboratory's key in PKCS#1 form, and a P-256
# signer. Never use these keys for anything else: they are public.
# Run from this directory; the outputs are committed.
set -euo pipefail
days=18250
openssl req -x509 -newkey rsa:2048 -nodes -keyout ca.key -out ca.pem -days $days \
  -subj "/O=accelcal tests/CN=accelcal test CA" 2>/dev/null
leaf() { # name, key options, subject
  openssl genpkey $2 -out "$1.key" 2>/dev/null
  openssl req -new -key "$1.key" -subj "$3" -out "$1.csr"
  openssl x509 -req -in "$1.csr" -CA ca.pem -CAkey ca.key -CAcreateserial -days $days \
    -out "$1.leaf.pem" 2>/dev/null
  cat "$1.leaf.pem" ca.pem > "$1.pem"
  rm "$1.csr" "$1.leaf.pem"
}
leaf lab "-algorithm RSA -pkeyopt rsa_keygen_bits:2048" "/C=CH/O=Inertial Test Lab/CN=DCC signing 2026"
leaf rotated "-algorithm RSA -pkeyopt rsa_keygen_bits:2048" "/C=CH/O=Inertial Test Lab/CN=DCC signing 2027"
leaf p256 "-algorithm EC -pkeyopt ec_paramgen_curve:P-256" "/C=CH/O=Inertial Test Lab/CN=DCC signing P-256"
leaf p384 "-algorithm EC -pkeyopt ec_paramgen_curve:P-384" "/C=CH/O=Inertial Test Lab/CN=DCC signing P-384"
openssl req -x509 -newkey rsa:1024 -nodes -keyout weak.key -out weak.pem -days $days \
  -subj "/O=accelcal tests/CN=weak" 2>/dev/null
openssl rsa -in lab.key -traditional -out lab.pkcs1.key 2>/dev/null
# An expired certificate (2020 to 2021) for its own key, from the test CA.
openssl genpkey -algorithm RSA -pkeyopt rsa_keygen_bits:2048 -out expired.key 2>/dev/null
openssl req -new -key expired.key -subj "/C=CH/O=Inertial Test Lab/CN=DCC signing 2020" -out expired.csr
ca=$(mktemp -d); touch "$ca/index.txt"; echo 01 > "$ca/serial"
printf '[ca]\ndefault_ca = t\n[t]\ndatabase = %s/index.txt\nserial = %s/serial\nnew_certs_dir = %s\ndefault_md = sha256\npolicy = p\n[p]\ncommonName = supplied\n' \
  "$ca" "$ca" "$ca" > "$ca/ca.cnf"
openssl ca -batch -config "$ca/ca.cnf" -cert ca.pem -keyfile ca.key -in expired.csr -out expired.pem \
  -startdate 20200101000000Z -enddate 20210101000000Z -notext 2>/dev/null
rm -rf "$ca" expired.csr ca.srl
