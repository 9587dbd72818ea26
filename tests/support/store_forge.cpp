#include "store_forge.hpp"

#include <filesystem>
#include <stdexcept>

#include "lz4_filter.hpp"

namespace dicer::test {

void forge_page(hid_t file, const std::string& dataset, hsize_t page,
                const std::function<void(std::vector<std::uint8_t>&)>& edit, bool keep_crc_valid) {
  // The CRC companions are LZ4 pages too: H5Dwrite needs the filter (the
  // HDF Group's plugin is installed for serial HDF5 only).
  store::register_lz4_filter();
  hid_t ds = H5Dopen2(file, dataset.c_str(), H5P_DEFAULT);
  if (ds < 0) throw std::runtime_error("forge_page: no dataset " + dataset);
  hid_t dcpl = H5Dget_create_plist(ds), type = H5Dget_type(ds);
  hsize_t chunk[2] = {0, 1};
  const int rank = H5Pget_chunk(dcpl, 2, chunk);
  const size_t elem = H5Tget_size(type);
  hsize_t offset[2] = {page * chunk[0], 0}, stored = 0;
  H5Dget_chunk_storage_size(ds, offset, &stored);
  std::vector<std::uint8_t> raw(stored), bytes;
  std::uint32_t mask = 0;
  if (H5Dread_chunk(ds, H5P_DEFAULT, offset, &mask, raw.data()) < 0) throw std::runtime_error("forge_page: read");
  store::decode_page(raw, bytes, chunk[0] * (rank == 2 ? chunk[1] : 1) * elem, "forge");
  // Shuffled datasets (every int64 table) are edited in their plain bytes.
  const bool shuffled = H5Pget_nfilters(dcpl) > 0 &&
                        H5Pget_filter2(dcpl, 0, nullptr, nullptr, nullptr, 0, nullptr, nullptr) == H5Z_FILTER_SHUFFLE;
  if (shuffled) {
    std::vector<std::uint8_t> plain;
    store::unshuffle_bytes(bytes, elem, plain);
    bytes.swap(plain);
  }
  edit(bytes);
  std::vector<std::uint8_t> stored_bytes = bytes;
  if (shuffled) store::shuffle_bytes(bytes, elem, stored_bytes);
  const std::vector<std::uint8_t> enc = store::encode_page(stored_bytes);
  if (H5Dwrite_chunk(ds, H5P_DEFAULT, 0, offset, enc.size(), enc.data()) < 0) throw std::runtime_error("forge_page: write");
  H5Tclose(type), H5Pclose(dcpl), H5Dclose(ds);
  if (!keep_crc_valid) return;
  const std::string crc_name = dataset + store::kPageCrcSuffix;
  hid_t cds = H5Dopen2(file, crc_name.c_str(), H5P_DEFAULT);
  hid_t sp = H5Dget_space(cds);
  hsize_t n = 0;
  H5Sget_simple_extent_dims(sp, &n, nullptr);
  std::vector<std::uint32_t> crc(n);
  H5Dread(cds, H5T_NATIVE_UINT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, crc.data());
  crc.at(page) = store::page_crc(bytes);
  if (H5Dwrite(cds, H5T_NATIVE_UINT32, H5S_ALL, H5S_ALL, H5P_DEFAULT, crc.data()) < 0)
    throw std::runtime_error("forge_page: cannot rewrite " + crc_name);
  H5Sclose(sp), H5Dclose(cds);
}

std::string edited_copy(const std::string& store, const std::string& path, const std::function<void(hid_t)>& edit) {
  std::filesystem::copy_file(store, path, std::filesystem::copy_options::overwrite_existing);
  store::register_lz4_filter();
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  if (f < 0) throw std::runtime_error("edited_copy: cannot open " + path);
  edit(f);
  H5Fclose(f);
  return path;
}

}  // namespace dicer::test
